//! `remote_start_ms`: `armor run` of ten counters, half of them placed on another host (an
//! `armor host` daemon in a network namespace of its own, joined to this one by a veth pair),
//! timed from its spawn until it logs that every module has its configuration, against the same
//! ten counters all local. Needs root and iproute2 (`ip netns`): where namespaces cannot be
//! made, the benchmark fails saying so.

use std::fmt::Write as _;
use std::process::Command;

use anyhow::{Context as _, bail};

use crate::Settings;
use crate::harness::LINK_TIMEOUT;
use crate::procs::{ChildGuard, sibling_binary};
use crate::startup::armor_startup;
use armor_bench_report::{Report, median};

pub const NAME: &str = "remote_start_ms";
const MODULES: usize = 10;
/// This side of the veth pair, and the far side (in the namespace).
pub const NEAR: &str = "10.78.0.1";
pub const FAR: &str = "10.78.0.2";

/// A namespace joined to this one by a veth pair; deleted on drop.
pub struct FarSide {
    pub ns: String,
    veth: String,
}

fn ip(args: &[&str]) -> anyhow::Result<()> {
    let output = Command::new("ip")
        .args(args)
        .output()
        .context("cannot run `ip` (iproute2)")?;
    if !output.status.success() {
        bail!(
            "`ip {}` failed: {} (network namespaces need root)",
            args.join(" "),
            String::from_utf8_lossy(&output.stderr).trim()
        );
    }
    Ok(())
}

impl FarSide {
    pub fn make() -> anyhow::Result<FarSide> {
        let tag = std::process::id() % 100_000;
        let side = FarSide {
            ns: format!("armor_bench_{tag}"),
            veth: format!("abn{tag}"),
        };
        ip(&["netns", "add", &side.ns])?;
        ip(&[
            "link", "add", &side.veth, "type", "veth", "peer", "name", "abf", "netns", &side.ns,
        ])?;
        ip(&["addr", "add", &format!("{NEAR}/24"), "dev", &side.veth])?;
        ip(&["link", "set", &side.veth, "up"])?;
        ip(&[
            "-n",
            &side.ns,
            "addr",
            "add",
            &format!("{FAR}/24"),
            "dev",
            "abf",
        ])?;
        ip(&["-n", &side.ns, "link", "set", "abf", "up"])?;
        ip(&["-n", &side.ns, "link", "set", "lo", "up"])?;
        Ok(side)
    }
}

impl Drop for FarSide {
    fn drop(&mut self) {
        let _ = ip(&["link", "del", &self.veth]);
        let _ = ip(&["netns", "del", &self.ns]);
    }
}

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let rounds = if settings.quick { 1 } else { 5 };
    let armor = sibling_binary("armor")?;
    let far = FarSide::make()?;
    let dir = tempfile::tempdir().context("cannot make a temporary folder")?;
    let split = dir.path().join("split.xml");
    let local = dir.path().join("local.xml");
    std::fs::write(&split, system_xml(true))?;
    std::fs::write(&local, system_xml(false))?;
    let mut host_command = Command::new("ip");
    host_command
        .args(["netns", "exec", &far.ns])
        .arg(&armor)
        .args(["host", "--name", "far", "--listen", &format!("{FAR}:7410")])
        .env("ARMOR_LOG", "info");
    let mut host = ChildGuard::spawn_capturing_stdout("armor host", host_command)?;
    let Some(lines) = host.take_stdout_lines() else {
        bail!("armor host: no stdout to read");
    };
    host.wait_line(&lines, "its address", LINK_TIMEOUT, |line| {
        line.starts_with(armor_runtime::host::HOST_READY_PREFIX)
            .then_some(())
    })?;
    let mut ours = Vec::with_capacity(rounds);
    let mut reference = Vec::with_capacity(rounds);
    for _ in 0..rounds {
        ours.push(armor_startup(&armor, &split)?);
        reference.push(armor_startup(&armor, &local)?);
    }
    host.check_alive()?;
    Ok(
        Report::single(NAME, "ms", median(&ours), median(&reference))
            .with("remote_modules", MODULES / 2)
            .with("reference_is", "the same ten counters all on this machine"),
    )
}

/// Ten counters, the odd ones on the far host when `split`.
fn system_xml(split: bool) -> String {
    let mut xml = format!("<system name=\"bench_remote\" host=\"{NEAR}\">\n");
    let _ = writeln!(xml, "  <host name=\"far\" address=\"{FAR}\"/>");
    for index in 0..MODULES {
        let host = if split && index % 2 == 1 {
            " host=\"far\""
        } else {
            ""
        };
        let _ = writeln!(xml, "  <module name=\"c{index}\" type=\"counter\"{host}/>");
    }
    xml.push_str("</system>\n");
    xml
}
