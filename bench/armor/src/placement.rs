//! Where the two processes of a round trip run, and placing them on purpose.
//!
//! On this project's VMs a wake-up on the *other* virtual CPU costs about 45 µs (the guest's
//! halt polling is off, so an idle vCPU halts and is woken through the hypervisor), and Linux
//! keeps a woken task on the CPU it last ran on while that CPU is idle: two processes that ping
//! each other mostly stay where they are, on one vCPU (a round trip of 14–18 µs) or on two
//! (50–75 µs). A latency line alternates blocks between two pairs that share the bench's thread
//! (it and our echo, it and the raw echo): three processes on two vCPUs, so unpinned the thread
//! can sit with only one of the two echoes, and that side's figure is the fast one. The latency
//! lines therefore also measure both pairs placed alike, on one vCPU and split over two.
//!
//! Placing goes through `taskset`, on the bench's own thread only (its other threads, the
//! in-process agent among them, stay free) and on every thread of a peer.

use std::process::{Command, Stdio};

use anyhow::{Context, bail};

/// The CPUs the calling thread may run on (`Cpus_allowed_list` of `/proc/thread-self/status`).
pub fn allowed_cpus() -> Vec<usize> {
    let Ok(status) = std::fs::read_to_string("/proc/thread-self/status") else {
        return Vec::new();
    };
    let Some(list) = status
        .lines()
        .find_map(|line| line.strip_prefix("Cpus_allowed_list:"))
    else {
        return Vec::new();
    };
    parse_cpu_list(list.trim())
}

/// A kernel CPU list (`0-3,6`) expanded.
fn parse_cpu_list(list: &str) -> Vec<usize> {
    let mut cpus = Vec::new();
    for part in list.split(',').filter(|part| !part.is_empty()) {
        match part.split_once('-') {
            Some((first, last)) => {
                if let (Ok(first), Ok(last)) = (first.parse::<usize>(), last.parse::<usize>()) {
                    cpus.extend(first..=last);
                }
            }
            None => cpus.extend(part.parse::<usize>()),
        }
    }
    cpus
}

/// The calling thread's id (from `/proc/thread-self`, which links to `PID/task/TID`).
pub fn own_thread() -> anyhow::Result<u32> {
    let link = std::fs::read_link("/proc/thread-self").context("no /proc/thread-self")?;
    link.file_name()
        .and_then(|name| name.to_str())
        .and_then(|name| name.parse().ok())
        .context("unreadable /proc/thread-self")
}

/// The CPU a thread last ran on (field 39 of its `stat`).
#[cfg(test)]
fn last_cpu(tid: u32) -> Option<usize> {
    let stat = std::fs::read_to_string(format!("/proc/{tid}/stat")).ok()?;
    // The fields after the command, which is in parentheses and may hold spaces: the state is
    // field 3, the processor field 39.
    let after = &stat[stat.rfind(')')? + 1..];
    after.split_whitespace().nth(36)?.parse().ok()
}

/// Lets thread `tid` (with `all_threads`, every thread of process `tid`) run only on `cpus`.
pub fn set(tid: u32, cpus: &[usize], all_threads: bool) -> anyhow::Result<()> {
    let list = cpus
        .iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join(",");
    let mut command = Command::new("taskset");
    if all_threads {
        command.arg("-a");
    }
    let status = command
        .args(["-p", "-c", &list, &tid.to_string()])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .context("cannot run taskset (util-linux)")?;
    if !status.success() {
        bail!("taskset -p -c {list} {tid} failed: {status}");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cpu_lists_expand_as_the_kernel_writes_them() {
        assert_eq!(parse_cpu_list("0-1"), [0, 1]);
        assert_eq!(parse_cpu_list("0,2-4,7"), [0, 2, 3, 4, 7]);
        assert_eq!(parse_cpu_list("3"), [3]);
        assert!(parse_cpu_list("").is_empty());
    }

    #[test]
    fn this_thread_is_placed_and_freed_again() {
        let allowed = allowed_cpus();
        assert!(!allowed.is_empty());
        let me = own_thread().expect("thread id");
        let first = allowed[0];
        set(me, &[first], false).expect("pinned");
        // A thread pinned to one CPU runs there from its next scheduling on.
        std::thread::yield_now();
        assert_eq!(last_cpu(me), Some(first));
        set(me, &allowed, false).expect("freed");
        assert_eq!(allowed_cpus(), allowed);
    }
}
