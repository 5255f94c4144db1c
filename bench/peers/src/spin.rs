//! `states_vs_spin`: the mission analysis (`armor_model::net::analyse`) on dining philosophers
//! against the Spin model checker on the same net translated to Promela.
//!
//! The translation (`promela`) gives every place a `byte` and the net one process looping over
//! one `d_step` per transition: guard on the input places, then take and put the tokens. A
//! `d_step` is one indivisible step, so Spin stores exactly one state per reachable marking and
//! both sides must report the same count. The verifier is compiled for the fastest exhaustive
//! safety search twice: breadth-first like ours (`gcc -O2 -DSAFETY -DNOCLAIM -DBFS`) and with
//! Spin's default depth-first search (`gcc -O2 -DSAFETY -DNOCLAIM`, run with a depth limit that
//! cannot truncate it); the reference is the faster of the two in the same run. Both run with `-E`
//! (deadlocks are the point of the philosophers, not an error). Spin's rate is its own figure
//! (`states, stored` over `pan: elapsed time`), which leaves out starting the process and
//! allocating the hash table: the comparison favours Spin. When that time rounds to zero, the
//! wall time of the `pan` run is used.

use std::fmt::Write as _;
use std::hint::black_box;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail, ensure};
use armor_model::net::{MissionNet, analyse, dining_philosophers};
use serde_json::json;

use crate::Settings;
use armor_bench_report::{Report, median};

pub const NAME: &str = "states_vs_spin";

/// The same limit as `armor check` and `armor run` (`armor_runtime::mission`).
const LIMIT_STATES: usize = armor_runtime::mission::ANALYSIS_LIMIT_STATES;

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let (sizes, rounds, round_time): (&[usize], usize, Duration) = if settings.quick {
        (&[5], 1, Duration::from_millis(20))
    } else {
        (&[10, 12, 14], 3, Duration::from_millis(300))
    };
    if which("spin").is_none() || which("gcc").is_none() {
        // Our side alone, so the line still says what we do; the ratio is then NaN.
        let net = dining_philosophers(sizes[0]);
        let ours = rate(round_time, || {
            Ok(analyse(black_box(&net), LIMIT_STATES).states)
        })?;
        return Ok(Report::single(NAME, "states/s", ours, f64::NAN)
            .with_states(analyse(&net, LIMIT_STATES).states)
            .with("philosophers", sizes[0])
            .with(
                "reference_is",
                "missing: Spin (Debian `spin`) and gcc are needed for the reference",
            ));
    }
    let folder = tempfile::tempdir().context("temporary folder for Spin")?;
    let mut detail = Vec::new();
    let mut last = None;
    for &n in sizes {
        let net = dining_philosophers(n);
        let analysis = analyse(&net, LIMIT_STATES);
        ensure!(
            !analysis.truncated,
            "{n} philosophers: more than {LIMIT_STATES} markings"
        );
        let states = analysis.states;
        let model = promela(&net);
        let bfs = build_pan(
            folder.path(),
            &format!("phil{n}-bfs"),
            &model,
            Search::BreadthFirst,
        )?;
        let dfs = build_pan(
            folder.path(),
            &format!("phil{n}-dfs"),
            &model,
            Search::DepthFirst,
        )?;
        let mut ours = Vec::new();
        let (mut spin_bfs, mut spin_dfs, mut spin_wall) = (Vec::new(), Vec::new(), Vec::new());
        for _ in 0..rounds {
            ours.push(rate(round_time, || {
                Ok(analyse(black_box(&net), LIMIT_STATES).states)
            })?);
            for (pan, search, rates) in [
                (&bfs, Search::BreadthFirst, &mut spin_bfs),
                (&dfs, Search::DepthFirst, &mut spin_dfs),
            ] {
                let run = run_pan(pan, states, search)?;
                if run.states != states {
                    bail!(
                        "{n} dining philosophers: our analysis found {states} reachable \
                         markings, Spin ({search:?}) {}",
                        run.states
                    );
                }
                rates.push(run.states as f64 / run.search_secs);
                if search == Search::BreadthFirst {
                    spin_wall.push(run.states as f64 / run.wall_secs);
                }
            }
        }
        let (ours, bfs, dfs, spin_wall) = (
            median(&ours),
            median(&spin_bfs),
            median(&spin_dfs),
            median(&spin_wall),
        );
        let (spin, search) = if dfs > bfs {
            (dfs, "depth-first")
        } else {
            (bfs, "breadth-first")
        };
        detail.push(json!({
            "philosophers": n,
            "states": states,
            "ours_states_per_s": crate::round4(ours),
            "spin_bfs_states_per_s": crate::round4(bfs),
            "spin_dfs_states_per_s": crate::round4(dfs),
            "spin_bfs_wall_states_per_s": crate::round4(spin_wall),
        }));
        last = Some((n, states, ours, spin, search));
    }
    let Some((n, states, ours, spin, search)) = last else {
        bail!("no size to measure");
    };
    Ok(Report::single(NAME, "states/s", ours, spin)
        .with_states(states)
        .with("spin_states", states)
        .with("philosophers", n)
        .with("spin_search", search)
        .with("goal", ">= 1x Spin, identical state counts")
        .with(
            "reference_is",
            "Spin 6 pan (gcc -O2 -DSAFETY -DNOCLAIM), the faster of its breadth-first (-DBFS) \
             and its default depth-first search in this run, its own search time",
        )
        .with("sizes", detail))
}

/// The net in Promela: one `byte` per place, one process, one `d_step` per transition.
pub fn promela(net: &MissionNet) -> String {
    let ident = |name: &str| -> String {
        let clean: String = name
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
            .collect();
        format!("p_{clean}")
    };
    let mut text = format!("/* {} */\n", net.name);
    for place in &net.places {
        let _ = writeln!(text, "byte {} = {};", ident(&place.name), place.tokens);
    }
    text.push_str("active proctype net() {\n  do\n");
    for transition in &net.transitions {
        let guard: Vec<String> = transition
            .inputs
            .iter()
            .map(|arc| format!("{} >= {}", ident(&arc.place), arc.weight))
            .collect();
        let guard = if guard.is_empty() {
            "true".to_owned()
        } else {
            guard.join(" && ")
        };
        let mut body = String::new();
        for arc in &transition.inputs {
            let _ = write!(body, " {0} = {0} - {1};", ident(&arc.place), arc.weight);
        }
        for arc in &transition.outputs {
            let _ = write!(body, " {0} = {0} + {1};", ident(&arc.place), arc.weight);
        }
        let _ = writeln!(
            text,
            "  :: d_step {{ {guard} ->{body} }} /* {} */",
            transition.name
        );
    }
    text.push_str("  od\n}\n");
    text
}

/// Spin's two exhaustive searches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Search {
    BreadthFirst,
    DepthFirst,
}

/// Writes `NAME.pml`, runs `spin -a` and compiles the verifier for `search`; returns its path.
fn build_pan(
    folder: &Path,
    name: &str,
    model: &str,
    search: Search,
) -> anyhow::Result<std::path::PathBuf> {
    let dir = folder.join(name);
    std::fs::create_dir_all(&dir)?;
    std::fs::write(dir.join("model.pml"), model)?;
    let output = Command::new("spin")
        .args(["-a", "model.pml"])
        .current_dir(&dir)
        .output()
        .context("running spin -a")?;
    ensure!(
        output.status.success(),
        "spin -a failed: {}",
        String::from_utf8_lossy(&output.stdout)
    );
    let mut args = vec!["-O2", "-DSAFETY", "-DNOCLAIM"];
    if search == Search::BreadthFirst {
        args.push("-DBFS");
    }
    let output = Command::new("gcc")
        .args(args)
        .args(["-o", "pan", "pan.c"])
        .current_dir(&dir)
        .output()
        .context("running gcc on pan.c")?;
    ensure!(
        output.status.success(),
        "gcc pan.c failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    Ok(dir.join("pan"))
}

struct PanRun {
    states: usize,
    search_secs: f64,
    wall_secs: f64,
}

/// Runs the verifier with a hash table sized for `expected` states (and, depth-first, a depth
/// limit no path of `expected` states can reach, so that the search is never truncated).
fn run_pan(pan: &Path, expected: usize, search: Search) -> anyhow::Result<PanRun> {
    let bits = (usize::BITS - (expected.max(1) * 4).leading_zeros()).clamp(16, 28);
    let mut args = vec!["-E".to_owned(), format!("-w{bits}")];
    if search == Search::DepthFirst {
        args.push(format!("-m{}", expected + 10));
    }
    let start = Instant::now();
    let output = Command::new(pan)
        .args(&args)
        .current_dir(pan.parent().unwrap_or(Path::new(".")))
        .output()
        .context("running pan")?;
    let wall_secs = start.elapsed().as_secs_f64();
    let text = String::from_utf8_lossy(&output.stdout);
    let states = text
        .lines()
        .find_map(|line| line.trim().strip_suffix("states, stored"))
        .and_then(|count| count.trim().parse::<usize>().ok())
        .with_context(|| format!("no `states, stored` in pan's output:\n{text}"))?;
    let search_secs = text
        .lines()
        .find_map(|line| line.trim().strip_prefix("pan: elapsed time"))
        .and_then(|rest| rest.split_whitespace().next()?.parse::<f64>().ok())
        .with_context(|| format!("no `pan: elapsed time` in pan's output:\n{text}"))?;
    let search_secs = if search_secs > 0.0 {
        search_secs
    } else {
        wall_secs
    };
    Ok(PanRun {
        states,
        search_secs,
        wall_secs,
    })
}

/// States per second of `explore`, repeated for at least `time`.
fn rate(time: Duration, mut explore: impl FnMut() -> anyhow::Result<usize>) -> anyhow::Result<f64> {
    let start = Instant::now();
    let mut states = 0;
    loop {
        states += black_box(explore()?);
        let elapsed = start.elapsed();
        if elapsed >= time {
            return Ok(states as f64 / elapsed.as_secs_f64());
        }
    }
}

/// The program `name` on `$PATH`.
pub fn which(name: &str) -> Option<std::path::PathBuf> {
    std::env::split_paths(&std::env::var_os("PATH")?)
        .map(|dir| dir.join(name))
        .find(|file| file.is_file())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn promela_has_a_byte_per_place_and_a_step_per_transition() {
        let net = dining_philosophers(2);
        let text = promela(&net);
        assert_eq!(text.matches("byte p_").count(), net.places.len());
        assert_eq!(text.matches(":: d_step").count(), net.transitions.len());
        assert!(text.contains("byte p_think_0 = 1;"));
        assert!(text.contains(
            ":: d_step { p_think_0 >= 1 && p_fork_0 >= 1 -> p_think_0 = p_think_0 - 1; \
             p_fork_0 = p_fork_0 - 1; p_has_left_0 = p_has_left_0 + 1; } /* take_left_0 */"
        ));
    }

    /// Needs Spin and gcc; skipped without them.
    #[test]
    fn spin_counts_the_same_states() {
        if which("spin").is_none() || which("gcc").is_none() {
            eprintln!("spin or gcc missing: skipped");
            return;
        }
        let folder = tempfile::tempdir().expect("temporary folder");
        for n in [2, 5] {
            let net = dining_philosophers(n);
            let pan = build_pan(folder.path(), &format!("p{n}"), &promela(&net)).expect("pan");
            let ours = analyse(&net, LIMIT_STATES).states;
            assert_eq!(run_pan(&pan, ours).expect("run").states, ours);
        }
    }
}
