//! `probe_50_cold_ms`: 50 module binaries probed (`--describe`) with no description cache,
//! against 50 spawns of `/bin/true` in the same run; then the same 50 served warm from
//! `armor_runtime::probe::ProbeCache` (keyed on path, size and modification time).
//!
//! The 50 binaries are symbolic links, each in its own folder (a module binary's file name must
//! name its type), to the built `armor-mod-*` binaries taken in turn (copies would be 40 MB
//! each). "Cold" means no description cache: the page cache holds the binaries after the first
//! round, as it does on a developer's machine. Ours is `probe::probe_all` (what `armor probe`
//! and `armor run` do: all at once, one thread each); the reference spawns the 50 `/bin/true`
//! at once and waits for them all. The sequential figures are given too.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use anyhow::{Context as _, bail, ensure};
use armor_runtime::probe::{self, DEFAULT_TIMEOUT, ProbeCache};

use crate::Settings;
use armor_bench_report::{Report, median};

pub const NAME: &str = "probe_50_cold_ms";

const BINARIES: usize = 50;

/// The folder of the built module binaries: `$ARMOR_MODULE_PATH`'s first folder, else the
/// workspace's `target/release`.
fn module_dir() -> PathBuf {
    match std::env::var_os(probe::ENV_MODULE_PATH) {
        Some(path) if !path.is_empty() => std::env::split_paths(&path).next().unwrap_or_default(),
        _ => Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/release"),
    }
}

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let rounds = if settings.quick { 1 } else { 7 };
    let dir = module_dir();
    let built = probe::list_modules(std::slice::from_ref(&dir));
    if built.is_empty() {
        bail!(
            "no armor-mod-* binary in {} (build them: cargo build --release --workspace \
             --exclude armor_studio, or set {})",
            dir.display(),
            probe::ENV_MODULE_PATH
        );
    }
    let folder = tempfile::tempdir().context("temporary folder")?;
    let mut links = Vec::with_capacity(BINARIES);
    for i in 0..BINARIES {
        let target = std::fs::canonicalize(&built[i % built.len()])?;
        let sub = folder.path().join(format!("m{i:02}"));
        std::fs::create_dir(&sub)?;
        let link = sub.join(target.file_name().context("a binary without a name")?);
        std::os::unix::fs::symlink(&target, &link)?;
        links.push(link);
    }
    let truth = which_true()?;

    let (mut ours, mut reference, mut ours_seq, mut reference_seq) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for _ in 0..rounds {
        ours.push(time_ms(|| {
            for (binary, result) in probe::probe_all(&links, DEFAULT_TIMEOUT) {
                result.with_context(|| format!("probing {}", binary.display()))?;
            }
            Ok(())
        })?);
        reference.push(time_ms(|| spawn_all(&truth))?);
        ours_seq.push(time_ms(|| {
            for binary in &links {
                probe::probe(binary, DEFAULT_TIMEOUT)
                    .with_context(|| format!("probing {}", binary.display()))?;
            }
            Ok(())
        })?);
        reference_seq.push(time_ms(|| {
            for _ in 0..BINARIES {
                spawn_one(&truth)?;
            }
            Ok(())
        })?);
    }

    // Warm: a fresh cache filled once, then served.
    let cache = ProbeCache::new(folder.path().join("cache"));
    for (binary, result) in cache.probe_all(&links, DEFAULT_TIMEOUT) {
        result.with_context(|| format!("probing {} into the cache", binary.display()))?;
    }
    let (mut warm_all, mut warm_seq) = (Vec::new(), Vec::new());
    for _ in 0..rounds {
        warm_all.push(time_ms(|| {
            for (binary, result) in cache.probe_all(&links, DEFAULT_TIMEOUT) {
                result.with_context(|| format!("warm probe of {}", binary.display()))?;
            }
            Ok(())
        })?);
        warm_seq.push(time_ms(|| {
            for binary in &links {
                cache.probe(binary, DEFAULT_TIMEOUT)?;
            }
            Ok(())
        })?);
    }
    let warm_all = median(&warm_all);
    let warm_one = median(&warm_seq) / BINARIES as f64;
    ensure!(warm_all.is_finite(), "no warm figure");
    Ok(
        Report::single(NAME, "ms", median(&ours), median(&reference))
            .with("binaries", BINARIES)
            .with("module_types", built.len())
            .with("sequential_ms", crate::round4(median(&ours_seq)))
            .with(
                "reference_sequential_ms",
                crate::round4(median(&reference_seq)),
            )
            .with("warm_50_ms", crate::round4(warm_all))
            .with("warm_one_ms", crate::round4(warm_one))
            .with("goal", "warm probe < 5 ms")
            .with(
                "reference_is",
                "50 spawns of /bin/true at once, waited for (same run)",
            ),
    )
}

fn which_true() -> anyhow::Result<PathBuf> {
    let truth = PathBuf::from("/bin/true");
    ensure!(truth.is_file(), "no /bin/true");
    Ok(truth)
}

fn spawn_one(program: &Path) -> anyhow::Result<()> {
    let status = Command::new(program)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()?;
    ensure!(status.success(), "{} failed", program.display());
    Ok(())
}

/// Spawns `BINARIES` copies of `program` at once, then waits for them all.
fn spawn_all(program: &Path) -> anyhow::Result<()> {
    let mut children = Vec::with_capacity(BINARIES);
    for _ in 0..BINARIES {
        children.push(
            Command::new(program)
                .stdin(Stdio::null())
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()?,
        );
    }
    for mut child in children {
        let status = child.wait()?;
        ensure!(status.success(), "{} failed", program.display());
    }
    Ok(())
}

fn time_ms(work: impl FnOnce() -> anyhow::Result<()>) -> anyhow::Result<f64> {
    let start = Instant::now();
    work()?;
    Ok(start.elapsed().as_secs_f64() * 1e3)
}
