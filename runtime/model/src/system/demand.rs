//! Activation on demand: which modules of a system run, and why.
//!
//! A mission (or the operator) names the modules it wants for themselves: a plan's leg names
//! its follower, not the avoider its commands pass through nor the sensors it reads. The rest
//! follows from the links, over modules whose `activation` is `on-demand` (the default):
//!
//! - a module that runs needs what it reads: the providers of its linked inputs run too,
//!   transitively (*needed by `follower.odometry`*);
//! - a wanted module's outputs must reach something that runs: a module fed by it, whose
//!   outputs lead (through such modules) to a module that runs, carries them on (*carries
//!   `follower.cmd_desired`*: the avoider between the follower and the mux).
//!
//! Modules that are not controllable (a mux, a simulator) run whatever is wanted, and their
//! inputs pull nothing: a mux takes whichever of its inputs speaks, it needs none of them.
//! `always` modules run throughout and pull their providers; `explicit` ones run only when
//! named. Held modules (stopped by hand, or stopped for a moment to start afresh) never run.
//!
//! [`demand`] is pure: the config server calls it at every change of the mission's wishes, the
//! operator's hand or the system file, and `armor ctl status` shows its reasons.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt;

use super::{Activation, Endpoint, ModuleInstance, SystemConfig};

/// Why a module runs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Reason {
    /// It is not controllable: it runs whenever its process does.
    NotControllable,
    /// Its `activation` is `always`.
    Always,
    /// Wanted for itself: `place cross_drive`, `by hand`, `no mission`.
    Wanted(String),
    /// A module that runs reads one of its outputs on this input.
    NeededBy(Endpoint),
    /// It takes this output of a wanted module and carries it on to a module that runs.
    Carries(Endpoint),
}

impl fmt::Display for Reason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Reason::NotControllable => f.write_str("not controllable"),
            Reason::Always => f.write_str("always"),
            Reason::Wanted(why) => f.write_str(why),
            Reason::NeededBy(input) => write!(f, "needed by {input}"),
            Reason::Carries(output) => write!(f, "carries {output}"),
        }
    }
}

impl Reason {
    /// Whether the module runs for its own sake, so that what it publishes must be carried on.
    fn drives(&self) -> bool {
        matches!(self, Reason::Wanted(_) | Reason::Carries(_))
    }
}

/// Every module of `system` that runs, with why: those `wanted` (module → why), the `always`
/// ones, those that are not `controllable`, and the closure of their needs (see the module
/// documentation); never one of `held`. A wanted name the system does not have is ignored.
pub fn demand(
    system: &SystemConfig,
    controllable: impl Fn(&ModuleInstance) -> bool,
    wanted: &BTreeMap<String, String>,
    held: &BTreeSet<String>,
) -> BTreeMap<String, Reason> {
    let pullable = |name: &str| {
        !held.contains(name)
            && system.module(name).is_some_and(|module| {
                controllable(module) && module.activation == Activation::OnDemand
            })
    };
    let mut running: BTreeMap<String, Reason> = BTreeMap::new();
    for module in &system.modules {
        let reason = if !controllable(module) {
            Some(Reason::NotControllable)
        } else if held.contains(&module.name) {
            None
        } else if let Some(why) = wanted.get(&module.name) {
            Some(Reason::Wanted(why.clone()))
        } else if module.activation == Activation::Always {
            Some(Reason::Always)
        } else {
            None
        };
        if let Some(reason) = reason {
            running.entry(module.name.clone()).or_insert(reason);
        }
    }
    loop {
        let before = running.len();
        // What a wanted module publishes is carried on by the modules that lead to one that runs.
        let drivers: Vec<String> = running
            .iter()
            .filter(|(_, reason)| reason.drives())
            .map(|(name, _)| name.clone())
            .collect();
        for driver in drivers {
            for link in system
                .links
                .iter()
                .filter(|link| link.from.module == driver)
            {
                let next = &link.to.module;
                if !running.contains_key(next)
                    && pullable(next)
                    && leads_to_running(system, next, &running, &pullable)
                {
                    running.insert(next.clone(), Reason::Carries(link.from.clone()));
                }
            }
        }
        // What runs and is not a mux or a simulator needs its providers.
        let needing: Vec<String> = running
            .iter()
            .filter(|(_, reason)| **reason != Reason::NotControllable)
            .map(|(name, _)| name.clone())
            .collect();
        for module in needing {
            for link in system.links.iter().filter(|link| link.to.module == module) {
                let provider = &link.from.module;
                if !running.contains_key(provider) && pullable(provider) {
                    running.insert(provider.clone(), Reason::NeededBy(link.to.clone()));
                }
            }
        }
        if running.len() == before {
            return running;
        }
    }
}

/// Whether an output of `start` reaches a module that runs, directly or through modules that
/// could be pulled in.
fn leads_to_running(
    system: &SystemConfig,
    start: &str,
    running: &BTreeMap<String, Reason>,
    pullable: &impl Fn(&str) -> bool,
) -> bool {
    let mut seen = BTreeSet::from([start.to_owned()]);
    let mut frontier = vec![start.to_owned()];
    while let Some(module) = frontier.pop() {
        for link in system
            .links
            .iter()
            .filter(|link| link.from.module == module)
        {
            let next = &link.to.module;
            if running.contains_key(next) {
                return true;
            }
            if pullable(next) && seen.insert(next.clone()) {
                frontier.push(next.clone());
            }
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    const ROBOT: &str = r#"<system name="robot">
  <module name="sim" type="sim"/>
  <module name="mapper" type="mapper"/>
  <module name="follower" type="follower"/>
  <module name="smoother" type="smoother"/>
  <module name="avoider" type="avoider"/>
  <module name="observer" type="observer"/>
  <module name="logger" type="logger"/>
  <module name="camera" type="camera" activation="explicit"/>
  <module name="clock" type="clock" activation="always"/>
  <module name="mux" type="mux"/>
  <link from="sim.odometry" to="mapper.odometry"/>
  <link from="mapper.pose" to="follower.pose"/>
  <link from="sim.scan" to="avoider.scan"/>
  <link from="camera.image" to="follower.image"/>
  <link from="follower.cmd_desired" to="smoother.cmd"/>
  <link from="follower.cmd_desired" to="logger.cmd"/>
  <link from="smoother.cmd" to="avoider.cmd_desired"/>
  <link from="avoider.cmd_vel" to="mux.auto"/>
  <link from="observer.cmd_vel" to="mux.observe"/>
  <link from="sim.odometry" to="observer.odometry"/>
  <link from="mux.cmd_vel" to="sim.cmd_vel"/>
</system>"#;

    /// The reasons as text, for the modules that run.
    fn check(wanted: &[(&str, &str)], held: &[&str], expected: &[(&str, &str)]) {
        let system = SystemConfig::parse(ROBOT).expect("parses");
        // In this system the mapper is controllable, as a mapper that may idle would be.
        let controllable = |module: &ModuleInstance| !matches!(module.name.as_str(), "sim" | "mux");
        let wanted = wanted
            .iter()
            .map(|(module, why)| ((*module).to_owned(), (*why).to_owned()))
            .collect();
        let held = held.iter().map(|module| (*module).to_owned()).collect();
        let found: Vec<(String, String)> = demand(&system, controllable, &wanted, &held)
            .into_iter()
            .map(|(module, reason)| (module, reason.to_string()))
            .collect();
        let expected: Vec<(String, String)> = expected
            .iter()
            .map(|(module, why)| ((*module).to_owned(), (*why).to_owned()))
            .collect();
        assert_eq!(found, expected);
    }

    #[test]
    fn nothing_wanted_runs_only_what_always_runs() {
        check(
            &[],
            &[],
            &[
                ("clock", "always"),
                ("mux", "not controllable"),
                ("sim", "not controllable"),
            ],
        );
    }

    #[test]
    fn a_follower_brings_its_providers_and_the_modules_its_commands_pass_through() {
        check(
            &[("follower", "place cross_drive")],
            &[],
            &[
                ("avoider", "carries smoother.cmd"),
                ("clock", "always"),
                ("follower", "place cross_drive"),
                ("mapper", "needed by follower.pose"),
                ("mux", "not controllable"),
                ("sim", "not controllable"),
                ("smoother", "carries follower.cmd_desired"),
            ],
        );
    }

    #[test]
    fn an_observer_brings_nothing_through_the_mux_or_the_simulator() {
        check(
            &[("observer", "place gate_arrival")],
            &[],
            &[
                ("clock", "always"),
                ("mux", "not controllable"),
                ("observer", "place gate_arrival"),
                ("sim", "not controllable"),
            ],
        );
    }

    #[test]
    fn held_modules_never_run_and_break_what_goes_through_them() {
        check(
            &[("follower", "by hand")],
            &["mapper", "avoider", "clock"],
            &[
                ("follower", "by hand"),
                ("mux", "not controllable"),
                ("sim", "not controllable"),
            ],
        );
    }

    #[test]
    fn an_explicit_module_runs_only_when_named() {
        check(
            &[("follower", "place a"), ("camera", "place a")],
            &["avoider"],
            &[
                ("camera", "place a"),
                ("clock", "always"),
                ("follower", "place a"),
                ("mapper", "needed by follower.pose"),
                ("mux", "not controllable"),
                ("sim", "not controllable"),
            ],
        );
    }

    #[test]
    fn unknown_names_are_ignored() {
        check(
            &[("ghost", "place a")],
            &[],
            &[
                ("clock", "always"),
                ("mux", "not controllable"),
                ("sim", "not controllable"),
            ],
        );
    }
}
