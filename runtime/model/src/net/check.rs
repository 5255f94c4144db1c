//! The checks of a mission against the system it runs on and the module descriptions.

use std::collections::{BTreeMap, BTreeSet};

use armor_module_api::describe::ModuleDescription;
use armor_module_api::xml::{Located, Pos};

use super::{EventRef, MissionNet};
use crate::fields::listing;
use crate::system::{ModuleInstance, SystemConfig, demand};

/// Every problem of the names a mission uses, sorted by position: the modules its places run
/// exist in `system` and can be started and stopped; their parameters are declared by the
/// module's type with valid values; the events of its transitions are `MODULE.EVENT` with the
/// event declared by the module's type, or `module.ID.failed` with `ID` in the system.
/// `descriptions` are keyed by module type; a module of a type without description is not
/// checked further (the system's own check reports the unknown type).
pub fn check_names(
    net: &MissionNet,
    system: &SystemConfig,
    descriptions: &BTreeMap<String, ModuleDescription>,
) -> Vec<Located> {
    let mut problems = Vec::new();
    let find = |name: &str, subject: &str, pos: Pos, problems: &mut Vec<Located>| {
        find_module(system, descriptions, name, subject, pos, problems)
    };
    for place in &net.places {
        let subject = format!("place `{}`", place.name);
        for module in &place.modules {
            // A subsystem stands for its modules; those that are not controllable run anyway.
            if system.module(module).is_none() && system.subsystem(module).is_some() {
                continue;
            }
            if let Some((instance, Some(description))) =
                find(module, &subject, place.pos, &mut problems)
                && !description.controllable
            {
                problems.push(Located::new(
                    place.pos,
                    format!(
                        "{subject}: module `{module}` ({}) cannot be started and stopped by a \
                         mission: it is not controllable and runs all the time",
                        type_of(instance)
                    ),
                ));
            }
        }
        for param in &place.params {
            let Some((instance, Some(description))) =
                find(&param.module, &subject, param.pos, &mut problems)
            else {
                continue;
            };
            match description.param(&param.name) {
                None => problems.push(Located::new(
                    param.pos,
                    format!(
                        "{subject}: module `{}` ({}) has no parameter `{}` (parameters: {})",
                        param.module,
                        type_of(instance),
                        param.name,
                        listing(description.params.iter().map(|spec| spec.name.as_str()))
                    ),
                )),
                Some(spec) => {
                    if let Err(why) = spec.check_value(&param.value) {
                        problems.push(Located::new(
                            param.pos,
                            format!(
                                "{subject}: parameter `{}` of module `{}` ({}): {why}",
                                param.name, param.module, spec.param_type
                            ),
                        ));
                    }
                }
            }
        }
    }
    let running = runs_somewhere(net, system, descriptions);
    for transition in &net.transitions {
        let Some(event) = &transition.condition.event else {
            continue;
        };
        let pos = transition.pos;
        match EventRef::parse(event) {
            Some(EventRef::Module { module, event }) => {
                let subject = format!("transition `{}`: event `{module}.{event}`", transition.name);
                let Some((instance, Some(description))) =
                    find(module, &subject, pos, &mut problems)
                else {
                    continue;
                };
                if description.event(event).is_some() && !running.contains(module) {
                    problems.push(Located::new(
                        pos,
                        format!(
                            "transition `{}`: waits for `{module}.{event}`, but no place of the \
                             mission runs `{module}`, nor anything that needs it: the event \
                             never comes",
                            transition.name
                        ),
                    ));
                }
                if description.event(event).is_none() {
                    problems.push(Located::new(
                        pos,
                        format!(
                            "transition `{}`: module `{module}` ({}) reports no event `{event}` \
                             (events: {})",
                            transition.name,
                            type_of(instance),
                            listing(description.events.iter().map(|spec| spec.name.as_str()))
                        ),
                    ));
                }
            }
            Some(EventRef::Failed { module }) => {
                let subject = format!(
                    "transition `{}`: fault event `module.{module}.failed`",
                    transition.name
                );
                find(module, &subject, pos, &mut problems);
            }
            // The run reports it itself, from what its team bridge says of the radio.
            Some(EventRef::LinkLost { .. }) => {}
            None => problems.push(Located::new(
                pos,
                format!(
                    "transition `{}`: `{event}` is not an event (MODULE.EVENT, module.ID.failed or \
                     link.lost.SECS)",
                    transition.name
                ),
            )),
        }
    }
    problems.sort_by_key(|problem| problem.pos);
    problems
}

impl MissionNet {
    /// The net with each place's subsystems (names of `system`'s subsystems where its
    /// modules are named) replaced by their modules, each named once: what the controller
    /// runs. A name that is neither stays as it is.
    pub fn with_subsystems_expanded(&self, system: &SystemConfig) -> MissionNet {
        let mut net = self.clone();
        for place in &mut net.places {
            let mut modules: Vec<String> = Vec::new();
            for name in &place.modules {
                for module in system.units(name).unwrap_or_else(|| vec![name.clone()]) {
                    if !modules.contains(&module) {
                        modules.push(module);
                    }
                }
            }
            place.modules = modules;
        }
        net
    }
}

/// The modules that run in some place of `net`: those each place names, closed over what they
/// need (activation on demand, [`crate::system::demand`]), and those that always run.
fn runs_somewhere(
    net: &MissionNet,
    system: &SystemConfig,
    descriptions: &BTreeMap<String, ModuleDescription>,
) -> BTreeSet<String> {
    let controllable = |instance: &ModuleInstance| {
        descriptions
            .get(&instance.module_type)
            .is_none_or(|description| description.controllable)
    };
    let held = BTreeSet::new();
    let mut running = BTreeSet::new();
    for place in &net.places {
        let wanted = place
            .modules
            .iter()
            .flat_map(|name| system.units(name).unwrap_or_default())
            .map(|module| (module, format!("place {}", place.name)))
            .collect();
        running.extend(demand(system, controllable, &wanted, &held).into_keys());
    }
    if net.places.is_empty() {
        running.extend(demand(system, controllable, &BTreeMap::new(), &held).into_keys());
    }
    running
}

/// The module instance `name` and its description, if known; reports a module missing from the
/// system, the message starting with `subject`.
fn find_module<'a>(
    system: &'a SystemConfig,
    descriptions: &'a BTreeMap<String, ModuleDescription>,
    name: &str,
    subject: &str,
    pos: Pos,
    problems: &mut Vec<Located>,
) -> Option<(&'a ModuleInstance, Option<&'a ModuleDescription>)> {
    let Some(instance) = system.module(name) else {
        let subsystems = system.all_subsystems();
        let also = if subsystems.is_empty() {
            String::new()
        } else {
            format!(
                "; subsystems: {}",
                listing(
                    subsystems
                        .iter()
                        .filter_map(|path| path.last().map(|s| s.name.as_str()))
                )
            )
        };
        problems.push(Located::new(
            pos,
            format!(
                "{subject}: no module `{name}` in the system (modules: {}{also})",
                listing(system.modules.iter().map(|module| module.name.as_str()))
            ),
        ));
        return None;
    };
    Some((instance, descriptions.get(&instance.module_type)))
}

fn type_of(instance: &ModuleInstance) -> String {
    format!("type {}", instance.module_type)
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::describe::{EventSpec, ParamSpec, ParamType};

    const SYSTEM: &str = r#"<system name="robot">
  <module name="nav" type="navigation"/>
  <module name="sim" type="sim"/>
  <module name="ui" type="console"/>
  <module name="cam" type="camera"/>
  <link from="cam.image" to="nav.image"/>
</system>"#;

    fn descriptions() -> BTreeMap<String, ModuleDescription> {
        let mut navigation = ModuleDescription::new("navigation", "goes places");
        navigation
            .params
            .push(ParamSpec::new("goal_x", ParamType::Float, ""));
        navigation
            .params
            .push(ParamSpec::new("verbose", ParamType::Bool, "").default("false"));
        for event in ["goal_reached", "blocked"] {
            navigation.events.push(EventSpec {
                name: event.into(),
                doc: String::new(),
            });
        }
        let sim = ModuleDescription::new("sim", "simulates");
        let mut console = ModuleDescription::new("console", "operator");
        console.controllable = false;
        // `camera` has no description: nothing more is checked about `cam`.
        [navigation, sim, console]
            .into_iter()
            .map(|description| (description.module_type.clone(), description))
            .collect()
    }

    /// The problems of the mission of `lines` (one per line from line 2) against [`SYSTEM`].
    fn check(lines: &[&str], expected: &[&str]) {
        let mut xml = String::from("<mission name=\"m\">\n");
        for line in lines {
            xml.push_str(line);
            xml.push('\n');
        }
        xml.push_str("</mission>");
        let net = MissionNet::parse(&xml).unwrap_or_else(|problems| {
            panic!(
                "{:?}",
                problems.iter().map(ToString::to_string).collect::<Vec<_>>()
            )
        });
        let system = SystemConfig::parse(SYSTEM).expect("valid system");
        let got: Vec<String> = check_names(&net, &system, &descriptions())
            .iter()
            .map(ToString::to_string)
            .collect();
        assert_eq!(got, expected, "for:\n{xml}");
    }

    #[test]
    fn clean_missions() {
        check(&[], &[]);
        check(
            &[
                "<place name=\"go\" tokens=\"1\"><module name=\"nav\"/><module name=\"sim\"/><module name=\"cam\"/>",
                "  <param module=\"nav\" name=\"goal_x\" value=\"-2.5\"/><param module=\"nav\" name=\"verbose\" value=\"true\"/>",
                "  <param module=\"cam\" name=\"anything\" value=\"goes\"/></place>",
                "<place name=\"done\" final=\"true\"/>",
                "<transition name=\"arrive\" event=\"nav.goal_reached\"><input place=\"go\"/><output place=\"done\"/></transition>",
                "<transition name=\"fault\" event=\"module.sim.failed\"><input place=\"go\"/></transition>",
                "<transition name=\"ui_fault\" event=\"module.ui.failed\"><input place=\"go\"/></transition>",
                "<transition name=\"cam_event\" event=\"cam.whatever\"><input place=\"go\"/></transition>",
            ],
            &[],
        );
    }

    #[test]
    fn an_event_of_a_module_that_never_runs_never_comes() {
        check(
            &[
                "<place name=\"look\" tokens=\"1\"><module name=\"nav\"/></place>",
                "<place name=\"idle\"/>",
                // `cam` runs in `look`: `nav` reads its image.
                "<transition name=\"seen\" event=\"cam.whatever\"><input place=\"look\"/><output place=\"idle\"/></transition>",
            ],
            &[],
        );
        check(
            &[
                "<place name=\"look\" tokens=\"1\"><module name=\"cam\"/></place>",
                "<transition name=\"arrive\" event=\"nav.blocked\"><input place=\"look\"/></transition>",
            ],
            &[
                "3:1: transition `arrive`: waits for `nav.blocked`, but no place of the mission runs `nav`, nor anything that needs it: the event never comes",
            ],
        );
    }

    #[test]
    fn unknown_modules_parameters_and_events() {
        check(
            &[
                "<place name=\"go\" tokens=\"1\"><module name=\"nac\"/><module name=\"ui\"/><module name=\"nav\"/>",
                "  <param module=\"nav\" name=\"goal\" value=\"1\"/>",
                "  <param module=\"nav\" name=\"goal_x\" value=\"ten\"/>",
                "  <param module=\"nac\" name=\"x\" value=\"1\"/></place>",
                "<transition name=\"arrive\" event=\"nav.goal_reched\"><input place=\"go\"/></transition>",
                "<transition name=\"b\" event=\"sim.done\"><input place=\"go\"/></transition>",
                "<transition name=\"c\" event=\"ghost.done\"><input place=\"go\"/></transition>",
                "<transition name=\"d\" event=\"module.ghost.failed\"><input place=\"go\"/></transition>",
            ],
            &[
                "2:1: place `go`: no module `nac` in the system (modules: nav, sim, ui, cam)",
                "2:1: place `go`: module `ui` (type console) cannot be started and stopped by a mission: it is not controllable and runs all the time",
                "3:3: place `go`: module `nav` (type navigation) has no parameter `goal` (parameters: goal_x, verbose)",
                "4:3: place `go`: parameter `goal_x` of module `nav` (float): `ten` is not a finite number",
                "5:3: place `go`: no module `nac` in the system (modules: nav, sim, ui, cam)",
                "6:1: transition `arrive`: module `nav` (type navigation) reports no event `goal_reched` (events: goal_reached, blocked)",
                "7:1: transition `b`: module `sim` (type sim) reports no event `done` (events: none)",
                "8:1: transition `c`: event `ghost.done`: no module `ghost` in the system (modules: nav, sim, ui, cam)",
                "9:1: transition `d`: fault event `module.ghost.failed`: no module `ghost` in the system (modules: nav, sim, ui, cam)",
            ],
        );
    }

    #[test]
    fn a_place_names_a_subsystem_for_all_its_modules() {
        let system = SystemConfig::parse(
            r#"<system name="robot">
  <module name="nav" type="navigation"/>
  <module name="sim" type="sim"/>
  <module name="ui" type="console"/>
  <subsystem name="robot"><member module="nav"/><member module="ui"/>
    <subsystem name="body"><member module="sim"/></subsystem></subsystem>
</system>"#,
        )
        .expect("valid system");
        let net = MissionNet::parse(
            r#"<mission name="m">
<place name="go" tokens="1"><module name="robot"/><module name="nav"/></place>
<place name="done" final="true"/>
<transition name="arrive" event="nav.goal_reached"><input place="go"/><output place="done"/></transition>
<place name="lost"><module name="wheels"/></place>
</mission>"#,
        )
        .expect("valid net");
        // The subsystem is a name the place may use (and its console, which is not
        // controllable, runs anyway); its follower's event comes.
        let got: Vec<String> = check_names(&net, &system, &descriptions())
            .iter()
            .map(ToString::to_string)
            .collect();
        assert_eq!(
            got,
            [
                "5:1: place `lost`: no module `wheels` in the system (modules: nav, sim, ui; subsystems: robot, body)"
            ]
        );
        let expanded = net.with_subsystems_expanded(&system);
        assert_eq!(expanded.places[0].modules, ["nav", "ui", "sim"]);
        assert_eq!(expanded.places[2].modules, ["wheels"]);
    }
}
