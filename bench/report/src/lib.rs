//! One benchmark's result line, the statistics behind it, and the loop both benchmark programs
//! run their benchmarks with ([`run_benches`]).

use std::io::Write as _;
use std::process::ExitCode;
use std::time::Duration;

use serde::Serialize;

/// A JSON line: `ours`, `reference`, their `unit` and `ratio` = ours / reference. Distributions
/// also carry percentiles (then `ours` and `reference` are the medians).
#[derive(Debug, Serialize)]
pub struct Report {
    pub bench: &'static str,
    pub ours: f64,
    pub reference: f64,
    pub unit: &'static str,
    pub ratio: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub p50: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub p99: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference_p50: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference_p99: Option<f64>,
    /// For a state-space exploration: the states each side found (the same on both).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub states: Option<usize>,
    /// Whatever else a benchmark says about its figures (`goal`, `reference_is`, ...).
    #[serde(flatten)]
    pub extra: serde_json::Map<String, serde_json::Value>,
}

impl Report {
    /// A single figure each side (a rate, or the median of a few rounds).
    pub fn single(bench: &'static str, unit: &'static str, ours: f64, reference: f64) -> Self {
        Self {
            bench,
            ours: round(ours),
            reference: round(reference),
            unit,
            ratio: round_ratio(ours / reference),
            p50: None,
            p99: None,
            reference_p50: None,
            reference_p99: None,
            states: None,
            extra: serde_json::Map::new(),
        }
    }

    /// The same report with a `states` field.
    pub fn with_states(mut self, states: usize) -> Self {
        self.states = Some(states);
        self
    }

    /// The same report with one more field.
    pub fn with(mut self, key: &str, value: impl Into<serde_json::Value>) -> Self {
        self.extra.insert(key.to_owned(), value.into());
        self
    }

    /// Two distributions of durations, reported in `scale` units per second (1e6 for µs).
    pub fn distribution(
        bench: &'static str,
        unit: &'static str,
        scale: f64,
        ours: &[Duration],
        reference: &[Duration],
    ) -> Self {
        let ours = Percentiles::of(ours, scale);
        let reference = Percentiles::of(reference, scale);
        Self {
            bench,
            ours: round(ours.p50),
            reference: round(reference.p50),
            unit,
            ratio: round_ratio(ours.p50 / reference.p50),
            p50: Some(round(ours.p50)),
            p99: Some(round(ours.p99)),
            reference_p50: Some(round(reference.p50)),
            reference_p99: Some(round(reference.p99)),
            states: None,
            extra: serde_json::Map::new(),
        }
    }
}

struct Percentiles {
    p50: f64,
    p99: f64,
}

impl Percentiles {
    fn of(samples: &[Duration], scale: f64) -> Self {
        let mut sorted: Vec<f64> = samples.iter().map(|d| d.as_secs_f64() * scale).collect();
        sorted.sort_by(f64::total_cmp);
        Self {
            p50: percentile(&sorted, 0.5),
            p99: percentile(&sorted, 0.99),
        }
    }
}

/// Nearest-rank percentile of sorted values (NaN when there are none).
pub fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let rank = (q * (sorted.len() - 1) as f64).round() as usize;
    sorted[rank.min(sorted.len() - 1)]
}

/// The median of a few values.
pub fn median(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    percentile(&sorted, 0.5)
}

/// Four significant digits, enough for any benchmark and easier to read.
pub fn round(value: f64) -> f64 {
    if !value.is_finite() || value == 0.0 {
        return value;
    }
    let magnitude = value.abs().log10().floor() as i32;
    let factor = 10f64.powi(3 - magnitude);
    (value * factor).round() / factor
}

fn round_ratio(value: f64) -> f64 {
    (value * 1000.0).round() / 1000.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_and_rounding() {
        let sorted: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(percentile(&sorted, 0.5), 51.0);
        assert_eq!(percentile(&sorted, 0.99), 99.0);
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(round(123_456.7), 123_500.0);
        assert_eq!(round(0.012_346), 0.012_35);
        let report = Report::single("x", "ms", 2.0, 4.0);
        assert_eq!(
            serde_json::to_string(&report).expect("json"),
            r#"{"bench":"x","ours":2.0,"reference":4.0,"unit":"ms","ratio":0.5}"#
        );
        let report = Report::single("y", "states/s", 3.0, 2.0).with_states(82);
        assert_eq!(
            serde_json::to_string(&report).expect("json"),
            r#"{"bench":"y","ours":3.0,"reference":2.0,"unit":"states/s","ratio":1.5,"states":82}"#
        );
        let report = Report::single("z", "x", 60.0, 50.0).with("goal", 50.0);
        assert_eq!(
            serde_json::to_string(&report).expect("json"),
            r#"{"bench":"z","ours":60.0,"reference":50.0,"unit":"x","ratio":1.2,"goal":50.0}"#
        );
    }
}

/// What every benchmark gets.
#[derive(Clone, Copy, Debug)]
pub struct Settings {
    /// Fewer rounds and smaller sizes: a check that the benchmark runs, not a figure.
    pub quick: bool,
}

/// A benchmark of a program's list.
pub struct Bench {
    pub name: &'static str,
    pub about: &'static str,
    pub run: fn(&Settings) -> anyhow::Result<Report>,
}

/// Lists `benches` and `on_request` (with `list`), or runs those `names` asks for and prints a
/// JSON line for each. With no names, every one of `benches` runs: the lines that need what the
/// README's two commands do not install (`on_request`) run only when named, and a message says
/// so. A failing benchmark does not hide the others; the exit status tells (2 for an unknown
/// name, 1 when any failed).
pub fn run_benches(
    benches: &[Bench],
    on_request: &[Bench],
    names: &[String],
    settings: Settings,
    list: bool,
) -> ExitCode {
    let every = || benches.iter().chain(on_request);
    if list {
        for bench in benches {
            println!("{:<26} {}", bench.name, bench.about);
        }
        for bench in on_request {
            println!("{:<26} {} (only when named)", bench.name, bench.about);
        }
        return ExitCode::SUCCESS;
    }
    let mut selected = Vec::new();
    if names.is_empty() {
        selected.extend(benches.iter());
        for bench in on_request {
            eprintln!(
                "note: `{}` runs only when named ({})",
                bench.name, bench.about
            );
        }
    }
    for name in names {
        match every().find(|bench| bench.name == name.as_str()) {
            Some(bench) => selected.push(bench),
            None => {
                let known: Vec<&str> = every().map(|bench| bench.name).collect();
                eprintln!(
                    "error: unknown benchmark `{name}` (known: {})",
                    known.join(", ")
                );
                return ExitCode::from(2);
            }
        }
    }
    let mut stdout = std::io::stdout().lock();
    let mut failed = 0;
    // Which benchmark runs, on standard error when it is a terminal (the figures go to
    // standard output, one JSON line each).
    let progress = indicatif::ProgressBar::with_draw_target(
        Some(selected.len() as u64),
        indicatif::ProgressDrawTarget::stderr_with_hz(4),
    );
    progress.set_style(
        indicatif::ProgressStyle::with_template("{pos}/{len} {msg} ({elapsed})")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    if !progress.is_hidden() {
        progress.enable_steady_tick(std::time::Duration::from_millis(250));
    }
    for bench in selected {
        progress.set_message(bench.name);
        let outcome = (bench.run)(&settings);
        progress.inc(1);
        progress.suspend(|| match outcome {
            Ok(report) => {
                let line = serde_json::to_string(&report).unwrap_or_default();
                let _ = writeln!(stdout, "{line}");
                let _ = stdout.flush();
            }
            Err(err) => {
                eprintln!("error: benchmark {}: {err:#}", bench.name);
                failed += 1;
            }
        });
    }
    progress.finish_and_clear();
    if failed > 0 {
        eprintln!("error: {failed} benchmark(s) failed");
        return ExitCode::FAILURE;
    }
    ExitCode::SUCCESS
}
