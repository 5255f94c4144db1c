//! What `armor run` does with the hosts a system declares (`<host name address/>`): connect to
//! their daemons before the modules start, measure each one's clock against ours (the run
//! assumes NTP-synchronised clocks: a mission's dates and delays are read on each machine's
//! clock) and refuse a mission with time constraints when a host is off by more than the
//! bound, and, while the run goes, say what the links report (a host lost or back, its
//! modules' output).

use std::collections::BTreeMap;
use std::time::Duration;

use armor_model::SystemConfig;
use armor_model::net::MissionNet;
use armor_module_api::auth::Secret;

use crate::config_server::ConfigServer;
use crate::console;
use crate::hosts::{HostLink, HostNote};

/// How long the run waits for every host's daemon before it starts without those away.
pub const JOIN_TIMEOUT: Duration = Duration::from_secs(5);
/// The clock skew a mission with time constraints tolerates by default.
pub const DEFAULT_MAX_SKEW: Duration = Duration::from_millis(50);

/// Whether a mission has dates or delays, which the clocks of its hosts must agree on.
pub fn has_time_constraints(net: &MissionNet) -> bool {
    net.transitions.iter().any(|transition| {
        transition.condition.at_unix_secs.is_some() || transition.condition.delay_secs.is_some()
    })
}

/// Connects to every declared host that has modules placed on it, waits for them (at most
/// [`JOIN_TIMEOUT`]), reports each one's clock offset, and refuses when a mission with time
/// constraints would run with a skew above `max_skew`.
pub fn connect_hosts(
    system: &SystemConfig,
    secret: Option<Secret>,
    orphan: Duration,
    time_constraints: bool,
    max_skew: Option<Duration>,
) -> anyhow::Result<BTreeMap<String, HostLink>> {
    let used: Vec<_> = system
        .hosts
        .iter()
        .filter(|host| {
            system.modules.iter().any(|module| {
                system
                    .placement(module)
                    .is_some_and(|at| at.name == host.name)
            })
        })
        .collect();
    let links: BTreeMap<String, HostLink> = used
        .iter()
        .map(|decl| {
            (
                decl.name.clone(),
                HostLink::start(decl, secret.clone(), &system.name, orphan),
            )
        })
        .collect();
    let joined_by = std::time::Instant::now() + JOIN_TIMEOUT;
    for link in links.values() {
        let left = joined_by.saturating_duration_since(std::time::Instant::now());
        if !link.wait_connected(left) {
            tracing::warn!(
                "host `{}` ({}) has not answered: its modules start when it does",
                link.name(),
                link.addr()
            );
        }
    }
    // The offset is measured right after joining.
    let deadline = std::time::Instant::now() + Duration::from_secs(2);
    for link in links.values() {
        while link.is_connected()
            && link.offset_ms().is_none()
            && std::time::Instant::now() < deadline
        {
            std::thread::sleep(Duration::from_millis(5));
        }
        let Some(offset_ms) = link.offset_ms() else {
            continue;
        };
        tracing::info!(
            "host `{}` ({}): clock offset {offset_ms:+.1} ms from this machine's",
            link.name(),
            link.addr()
        );
        if time_constraints
            && let Some(max) = max_skew
            && offset_ms.abs() > max.as_secs_f64() * 1e3
        {
            anyhow::bail!(
                "host `{}`'s clock is {:.1} ms off this machine's (more than {} ms): the \
                 mission's dates and delays would not hold across hosts; synchronise the \
                 clocks (NTP), or run with --max-clock-skew-ms N (0: any)",
                link.name(),
                offset_ms.abs(),
                max.as_millis()
            );
        }
    }
    Ok(links)
}

/// Says what the host links report since the last call: a host lost or back (also on the
/// health stream, for each module placed there), its modules' output lines.
pub fn take_notes(hosts: &BTreeMap<String, HostLink>, server: &ConfigServer) {
    for link in hosts.values() {
        for note in link.take_notes() {
            match note {
                HostNote::Log { module, line } => console::out_line(&format!("[{module}] {line}")),
                HostNote::Joined {
                    offset_ms,
                    round_trip_ms,
                } => tracing::info!(
                    "host `{}` ({}) joined: clock offset {offset_ms:+.1} ms, round trip \
                     {round_trip_ms:.1} ms",
                    link.name(),
                    link.addr()
                ),
                HostNote::Lost { why } => {
                    tracing::error!(
                        "host `{}` ({}) lost ({why}): its modules are down until it comes back",
                        link.name(),
                        link.addr()
                    );
                    let loaded = server.loaded();
                    for module in &loaded.system.modules {
                        if loaded
                            .system
                            .placement(module)
                            .is_some_and(|host| host.name == link.name())
                        {
                            server.report_health(
                                &module.name,
                                "failed",
                                &format!("its host `{}` is lost", link.name()),
                            );
                        }
                    }
                }
                HostNote::Unreachable { why } => {
                    tracing::warn!("host `{}` unreachable: {why}; trying again", link.name())
                }
                HostNote::SpawnFailed { module, error } => {
                    tracing::error!(module, "cannot start on host `{}`: {error}", link.name());
                }
            }
        }
    }
}
