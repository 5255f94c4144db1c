//! `armor check`, `armor compile` and the other one-shot commands, run as a user would, and
//! their `FILE:LINE:COL: message` lines read back.

use std::path::Path;
use std::process::{Command, Output};

use crate::{bin, bin_dir, workspace_root};

/// `armor` with `args`, from the workspace root, with the workspace's modules.
pub fn armor(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(bin("armor"))
        .args(args)
        .env("ARMOR_MODULE_PATH", bin_dir())
        .current_dir(workspace_root())
        .output()
        .unwrap()
}

pub fn output_text(output: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    )
}

/// The `FILE:LINE:COL: message` lines about `file` in the output: (line, col, message).
pub fn located(output: &Output, file: &Path) -> Vec<(usize, usize, String)> {
    let prefix = format!("{}:", file.display());
    output_text(output)
        .lines()
        .filter_map(|line| {
            let mut parts = line.strip_prefix(&prefix)?.splitn(3, ':');
            let line_no = parts.next()?.parse().ok()?;
            let col = parts.next()?.parse().ok()?;
            Some((line_no, col, parts.next()?.trim().to_owned()))
        })
        .collect()
}

/// The 1-based number of the first line of `text` containing `needle`.
pub fn line_of(text: &str, needle: &str) -> usize {
    text.lines()
        .position(|line| line.contains(needle))
        .unwrap_or_else(|| panic!("no `{needle}` in {text}"))
        + 1
}

/// A refusal: exit status 1 (not a panic's 101), a message at `line` saying `says`.
pub fn assert_refused(output: &Output, file: &Path, line: usize, says: &[&str]) {
    let all = output_text(output);
    assert_eq!(output.status.code(), Some(1), "{all}");
    assert!(!all.contains("panicked"), "{all}");
    let problems = located(output, file);
    assert!(
        problems.iter().any(|(at, col, message)| *at == line
            && *col > 0
            && says.iter().all(|word| message.contains(word))),
        "expected a message at line {line} saying {says:?}:\n{all}"
    );
}
