//! How the station view gets its team's data: it starts `armor-team station --json` and reads
//! its standard output, one [`StationEvent`] a line, and writes commands to its standard
//! input, one a line (`ROBOT|all COMMAND [ARGS]`).
//!
//! The studio links no zenoh: `armor-team` is the only program that does (its sessions, the
//! Noise handshakes, the seals), so `cargo build` of the studio stays as long as it was, and
//! the station program the studio runs is the one an operator runs on a terminal.

use std::io::{BufRead as _, BufReader, Write as _};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{Receiver, Sender, channel};

use anyhow::Context as _;
use armor_protocol::team::StationEvent;

/// What comes from the station program.
#[derive(Clone, Debug, PartialEq)]
pub enum FromStation {
    Event(StationEvent),
    /// The program ended, or a line could not be read: the reason.
    Closed(String),
}

/// Both ends of a station: events in, command lines out. Tests and the benchmark make one from
/// channels ([`Link::pair`]); the window from the station program ([`Link::spawn`]).
pub struct Link {
    pub events: Receiver<FromStation>,
    pub commands: Sender<String>,
    /// The station program, killed when the link goes.
    child: Option<Child>,
}

impl std::fmt::Debug for Link {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Link")
            .field("child", &self.child.as_ref().map(Child::id))
            .finish()
    }
}

impl Drop for Link {
    fn drop(&mut self) {
        if let Some(child) = &mut self.child {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

impl Link {
    /// A link with no program behind it: the other ends of its two channels.
    pub fn pair() -> (Link, Sender<FromStation>, Receiver<String>) {
        let (event_tx, events) = channel();
        let (commands, command_rx) = channel();
        (
            Link {
                events,
                commands,
                child: None,
            },
            event_tx,
            command_rx,
        )
    }

    /// Starts `program station --json ARGS…` (its arguments as `armor-team station` takes
    /// them: `--key`, `--robot`, `--connect`…).
    pub fn spawn(program: &PathBuf, args: &[String]) -> anyhow::Result<Link> {
        let mut child = Command::new(program)
            .arg("station")
            .arg("--json")
            .args(["--print-every-secs", "0.5"])
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .with_context(|| format!("cannot start {}", program.display()))?;
        let (stdout, mut stdin) = match (child.stdout.take(), child.stdin.take()) {
            (Some(stdout), Some(stdin)) => (stdout, stdin),
            _ => {
                let _ = child.kill();
                anyhow::bail!("{} started without its pipes", program.display());
            }
        };
        let (event_tx, events) = channel();
        let (commands, command_rx) = channel::<String>();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let event = match line {
                    Ok(line) => match serde_json::from_str::<StationEvent>(&line) {
                        Ok(event) => FromStation::Event(event),
                        // Not one of its lines (a message of a library): skipped.
                        Err(_) => continue,
                    },
                    Err(err) => FromStation::Closed(format!("cannot read the station: {err}")),
                };
                if event_tx.send(event).is_err() {
                    return;
                }
            }
            let _ = event_tx.send(FromStation::Closed(
                "the station program ended (see its messages on the terminal)".to_owned(),
            ));
        });
        std::thread::spawn(move || {
            for line in command_rx {
                if writeln!(stdin, "{line}")
                    .and_then(|()| stdin.flush())
                    .is_err()
                {
                    return;
                }
            }
        });
        Ok(Link {
            events,
            commands,
            child: Some(child),
        })
    }
}

/// `armor-team` beside the studio's own program (as `cargo build` and an install put them),
/// else the one on the `PATH`.
pub fn team_program() -> PathBuf {
    std::env::current_exe()
        .ok()
        .and_then(|exe| Some(exe.parent()?.join("armor-team")))
        .filter(|path| path.is_file())
        .unwrap_or_else(|| PathBuf::from("armor-team"))
}
