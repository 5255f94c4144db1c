//! What the `armor` command prints: log lines on the terminal, above the live progress line
//! when one is drawn (it is cleared, the line written, and drawn again, so the two never mix),
//! and, once a run has its folder, the same lines in that folder's log file.
//!
//! Every line goes through here: the command's own log (`init_logging` installs the writer) and
//! the modules' output that `armor run` copies with their names.

use std::fs::File;
use std::io::{LineWriter, Write};
use std::sync::{Mutex, PoisonError};

use indicatif::ProgressBar;

struct Console {
    /// The progress line being drawn, if any.
    bar: Option<ProgressBar>,
    /// The run's log file, if any.
    log: Option<LineWriter<File>>,
}

static CONSOLE: Mutex<Console> = Mutex::new(Console {
    bar: None,
    log: None,
});

fn with<R>(f: impl FnOnce(&mut Console) -> R) -> R {
    f(&mut CONSOLE.lock().unwrap_or_else(PoisonError::into_inner))
}

/// Which stream a line goes to on the terminal.
#[derive(Clone, Copy)]
enum Stream {
    Out,
    Err,
}

fn write(stream: Stream, bytes: &[u8]) {
    with(|console| {
        let to_terminal = || {
            let _ = match stream {
                Stream::Out => {
                    let mut out = std::io::stdout().lock();
                    out.write_all(bytes).and_then(|()| out.flush())
                }
                Stream::Err => std::io::stderr().lock().write_all(bytes),
            };
        };
        match &console.bar {
            Some(bar) => bar.suspend(to_terminal),
            None => to_terminal(),
        }
        if let Some(log) = &mut console.log {
            let _ = log.write_all(bytes);
        }
    });
}

/// Prints one line on standard output (and into the log).
pub fn out_line(line: &str) {
    write(Stream::Out, format!("{line}\n").as_bytes());
}

/// Every line from now on is also written to `file`.
pub fn log_to(file: File) {
    with(|console| console.log = Some(LineWriter::new(file)));
}

/// Lines are written above `bar` from now on (`None`: no bar any more).
pub fn show_bar(bar: Option<ProgressBar>) {
    with(|console| console.bar = bar);
}

/// Flushes and closes the log file.
pub fn close_log() {
    with(|console| {
        if let Some(mut log) = console.log.take() {
            let _ = log.flush();
        }
    });
}

/// Installs the command's log (`ARMOR_LOG` or `RUST_LOG` filters it, `info` by default) in
/// the same format as the modules', written through the console.
pub fn init_logging() {
    let filter = std::env::var("ARMOR_LOG")
        .or_else(|_| std::env::var("RUST_LOG"))
        .unwrap_or_else(|_| "info".to_owned());
    let _ = tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::new(filter))
        .with_writer(|| EventWriter(Vec::new()))
        .with_ansi(false)
        .without_time()
        .with_target(false)
        .try_init();
}

/// One log event, formatted into a buffer and written as a whole when dropped.
struct EventWriter(Vec<u8>);

impl Write for EventWriter {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.extend_from_slice(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Drop for EventWriter {
    fn drop(&mut self) {
        if !self.0.is_empty() {
            write(Stream::Err, &self.0);
        }
    }
}

/// A spinner on standard error while long work goes on (only on a terminal), with what is
/// being done and the time it has taken; log lines are written above it. Cleared when dropped.
pub struct Spinner(indicatif::ProgressBar);

impl Spinner {
    pub fn start(message: impl Into<std::borrow::Cow<'static, str>>) -> Spinner {
        let bar =
            ProgressBar::with_draw_target(None, indicatif::ProgressDrawTarget::stderr_with_hz(10));
        bar.set_style(
            indicatif::ProgressStyle::with_template("{spinner} {msg} ({elapsed})")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
        );
        bar.set_message(message);
        if !bar.is_hidden() {
            bar.tick();
            bar.enable_steady_tick(std::time::Duration::from_millis(100));
            show_bar(Some(bar.clone()));
        }
        Spinner(bar)
    }

    /// Says what is being done now.
    pub fn set(&self, message: impl Into<std::borrow::Cow<'static, str>>) {
        self.0.set_message(message);
    }
}

impl Drop for Spinner {
    fn drop(&mut self) {
        show_bar(None);
        self.0.finish_and_clear();
    }
}
