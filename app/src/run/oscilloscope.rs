//! The hierarchy oscilloscope (after JDE's): the run's modules as a tree — the system (and
//! the mission's place), the subsystems of the system file with their modules (nested as they
//! are), each arbiter with the behaviours that compete under it, then the other
//! modules — each with its state coloured (a behaviour's `slept`, `checking`, `ready`,
//! `winner`, the arbiter's winner marked), its cycle time and rates and its on/off switch
//! ([`monitor::module_row`]); and a time line of the behaviours' state changes, one lane per
//! module, scrubbed with a slider that says every state at the chosen moment.

use std::collections::{BTreeMap, VecDeque};

use armor_protocol::{BehaviourChange, BehaviourState, ModuleStatus, Request, Status};
use egui::{Color32, RichText, Stroke, Ui};
use egui_plot::{Line, Plot, VLine};

use super::monitor;
use super::session::Sample;

pub fn behaviour_colour(state: BehaviourState) -> Color32 {
    match state {
        BehaviourState::Slept => Color32::from_rgb(130, 130, 130),
        BehaviourState::Checking => Color32::from_rgb(215, 150, 30),
        BehaviourState::Ready => Color32::from_rgb(60, 120, 215),
        BehaviourState::Winner => Color32::from_rgb(40, 170, 70),
    }
}

/// Whether a module arbitrates (says who is in control).
fn is_arbiter(module: &ModuleStatus) -> bool {
    module.winner.is_some() || module.module_type == "arbiter"
}

/// The tree. Returns what the operator asked of the modules.
pub fn tree_ui(
    ui: &mut Ui,
    status: &Status,
    history: &BTreeMap<String, VecDeque<Sample>>,
    running: bool,
) -> Vec<Request> {
    let mut requests = Vec::new();
    let mut row = |ui: &mut Ui, module: &ModuleStatus| {
        if let Some(state) = module.behaviour {
            let winner = state == BehaviourState::Winner;
            let text = if winner {
                format!("★ {} in control", module.name)
            } else {
                format!("{}: {}", module.name, state.as_str())
            };
            let mut label = RichText::new(text).color(behaviour_colour(state));
            if winner {
                label = label.strong();
            }
            ui.label(label);
        }
        if let Some(request) = monitor::module_row(ui, module, history.get(&module.name), running) {
            requests.push(request);
        }
        ui.separator();
    };
    let place = status.mission.as_ref().map(|mission| {
        let places: Vec<&String> = mission.marking.keys().collect();
        format!(
            " · place {}",
            places
                .iter()
                .map(|p| p.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        )
    });
    let root = format!("system {}{}", status.system, place.unwrap_or_default());
    egui::CollapsingHeader::new(root)
        .id_salt("osc-root")
        .default_open(true)
        .show(ui, |ui| {
            // With subsystems: place → subsystems → modules, the rest after them.
            let grouped: Vec<&ModuleStatus> = status
                .modules
                .iter()
                .filter(|m| !m.subsystems.is_empty())
                .collect();
            subsystem_tree(ui, &grouped, 0, &mut row);
            let loose: Vec<&ModuleStatus> = status
                .modules
                .iter()
                .filter(|m| m.subsystems.is_empty())
                .collect();
            let behaviours: Vec<&ModuleStatus> = loose
                .iter()
                .copied()
                .filter(|m| m.behaviour.is_some())
                .collect();
            for arbiter in loose.iter().copied().filter(|m| is_arbiter(m)) {
                let title = format!(
                    "⚖ {} — in control: {}",
                    arbiter.name,
                    arbiter.winner.as_deref().unwrap_or("none")
                );
                egui::CollapsingHeader::new(title)
                    .id_salt(("osc-arbiter", &arbiter.name))
                    .default_open(true)
                    .show(ui, |ui| {
                        row(ui, arbiter);
                        for behaviour in &behaviours {
                            row(ui, behaviour);
                        }
                    });
            }
            let has_arbiter = loose.iter().copied().any(is_arbiter);
            // Behaviours are listed under their arbiter when there is one.
            let others: Vec<&ModuleStatus> = loose
                .iter()
                .copied()
                .filter(|m| !(is_arbiter(m) || has_arbiter && m.behaviour.is_some()))
                .collect();
            if others.is_empty() {
                return;
            }
            let title = if grouped.is_empty() {
                "modules"
            } else {
                "modules in no subsystem"
            };
            egui::CollapsingHeader::new(title)
                .id_salt("osc-others")
                .default_open(true)
                .show(ui, |ui| {
                    for module in others {
                        row(ui, module);
                    }
                });
        });
    requests
}

/// The subsystems at `depth` of `modules` (each in one, at least that deep), one header each
/// in the order they first come, with their modules (an arbiter's winner said on its row)
/// and the subsystems inside.
fn subsystem_tree(
    ui: &mut Ui,
    modules: &[&ModuleStatus],
    depth: usize,
    row: &mut dyn FnMut(&mut Ui, &ModuleStatus),
) {
    let mut names: Vec<&str> = Vec::new();
    for module in modules {
        if let Some(name) = module.subsystems.get(depth)
            && !names.contains(&name.as_str())
        {
            names.push(name);
        }
    }
    for name in names {
        let inside: Vec<&ModuleStatus> = modules
            .iter()
            .copied()
            .filter(|m| m.subsystems.get(depth).is_some_and(|s| s == name))
            .collect();
        let winner = inside
            .iter()
            .find_map(|m| m.winner.as_deref().filter(|_| is_arbiter(m)));
        let title = match winner {
            Some(winner) => format!("▣ {name} — in control: {winner}"),
            None => format!("▣ {name} · {} modules", inside.len()),
        };
        egui::CollapsingHeader::new(title)
            .id_salt(("osc-subsystem", depth, name))
            .default_open(true)
            .show(ui, |ui| {
                for module in inside.iter().filter(|m| m.subsystems.len() == depth + 1) {
                    if is_arbiter(module) {
                        ui.label(
                            RichText::new(format!(
                                "⚖ {} — in control: {}",
                                module.name,
                                module.winner.as_deref().unwrap_or("none")
                            ))
                            .strong(),
                        );
                    }
                    row(ui, module);
                }
                subsystem_tree(ui, &inside, depth + 1, row);
            });
    }
}

/// Each module's state at `at_secs`, from the time line (the last change at or before it).
pub fn states_at(
    changes: &[BehaviourChange],
    at_secs: f64,
) -> BTreeMap<String, Option<BehaviourState>> {
    let mut states = BTreeMap::new();
    for change in changes.iter().filter(|c| c.run_secs <= at_secs) {
        states.insert(change.module.clone(), change.state);
    }
    states
}

/// The time line of state changes, one lane per module, and the scrubber; `at_secs` is the
/// moment picked (`None`: now).
pub fn timeline_ui(ui: &mut Ui, status: &Status, at_secs: &mut Option<f64>) {
    let changes = &status.behaviour_changes;
    if changes.is_empty() {
        ui.label(RichText::new("no behaviour has said whether it applies yet").weak());
        return;
    }
    let mut lanes: Vec<&str> = changes.iter().map(|c| c.module.as_str()).collect();
    lanes.sort_unstable();
    lanes.dedup();
    let first = changes.first().map_or(0.0, |c| c.run_secs);
    let end = status.run_secs.max(first);
    // What the bars' colours say, once for every lane.
    ui.horizontal_wrapped(|ui| {
        for state in [
            BehaviourState::Winner,
            BehaviourState::Ready,
            BehaviourState::Checking,
            BehaviourState::Slept,
        ] {
            ui.label(RichText::new("■").color(behaviour_colour(state)));
            ui.label(state.as_str());
        }
    });
    Plot::new("osc-timeline")
        .height(24.0 * lanes.len() as f32 + 30.0)
        .allow_scroll(false)
        .allow_zoom([true, false])
        // Room above the top lane for its name.
        .include_y(-0.5)
        .include_y(lanes.len() as f64)
        .show_axes([true, false])
        .show(ui, |plot| {
            for (lane, module) in lanes.iter().enumerate() {
                let y = lane as f64;
                let mine: Vec<&BehaviourChange> =
                    changes.iter().filter(|c| c.module == *module).collect();
                for (index, change) in mine.iter().enumerate() {
                    let Some(state) = change.state else { continue };
                    let until = mine.get(index + 1).map_or(end, |next| next.run_secs);
                    plot.line(
                        Line::new(
                            format!("{module} {}", state.as_str()),
                            vec![[change.run_secs, y], [until, y]],
                        )
                        .stroke(Stroke::new(8.0, behaviour_colour(state))),
                    );
                }
                // From the lane's start rightwards, above its bar: a name centred on the start
                // would be cut in half by the plot's left edge.
                plot.text(
                    egui_plot::Text::new(
                        *module,
                        [first, y + 0.2].into(),
                        RichText::new(*module).text_style(egui::TextStyle::Body),
                    )
                    .anchor(egui::Align2::LEFT_BOTTOM),
                );
            }
            if let Some(at) = at_secs {
                plot.vline(VLine::new("scrubbed", *at).color(Color32::WHITE));
            }
        });
    ui.horizontal(|ui| {
        let mut now = at_secs.is_none();
        if ui.checkbox(&mut now, "now").changed() {
            *at_secs = if now { None } else { Some(end) };
        }
        let mut at = at_secs.unwrap_or(end);
        let slider = ui.add_enabled(
            at_secs.is_some(),
            egui::Slider::new(&mut at, first..=end).text("s of run time"),
        );
        if slider.changed() {
            *at_secs = Some(at);
        }
    });
    let shown = at_secs.unwrap_or(end);
    ui.horizontal_wrapped(|ui| {
        for (module, state) in states_at(changes, shown) {
            let (text, colour) = match state {
                Some(state) => (
                    format!("{module}: {}", state.as_str()),
                    behaviour_colour(state),
                ),
                None => (format!("{module}: gone"), Color32::GRAY),
            };
            ui.label(RichText::new(text).color(colour));
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_states_at_a_moment_are_the_last_changes_before_it() {
        let change = |run_secs: f64, module: &str, state: BehaviourState| BehaviourChange {
            run_secs,
            module: module.into(),
            state: Some(state),
        };
        let changes = [
            change(1.0, "follower", BehaviourState::Winner),
            change(1.0, "vff", BehaviourState::Checking),
            change(5.0, "vff", BehaviourState::Winner),
            change(5.0, "follower", BehaviourState::Ready),
            change(7.5, "vff", BehaviourState::Checking),
        ];
        let at = |secs| {
            states_at(&changes, secs)
                .into_iter()
                .map(|(m, s)| format!("{m} {}", s.map_or("gone", BehaviourState::as_str)))
                .collect::<Vec<_>>()
        };
        assert_eq!(at(0.5), Vec::<String>::new());
        assert_eq!(at(6.0), ["follower ready", "vff winner"]);
        assert_eq!(at(8.0), ["follower ready", "vff checking"]);
    }

    /// The tree of a run whose system has subsystems: place → subsystems (nested) → modules,
    /// the arbiter's winner said on its subsystem, the modules in none after them.
    #[test]
    fn the_tree_goes_place_subsystems_modules() {
        use armor_protocol::{MissionStatus, ModuleState};
        use egui_kittest::kittest::Queryable as _;
        let module = |name: &str, subsystems: &[&str]| ModuleStatus {
            name: name.into(),
            module_type: name.into(),
            state: ModuleState::Running,
            controllable: true,
            subsystems: subsystems.iter().map(|s| (*s).to_owned()).collect(),
            ..ModuleStatus::default()
        };
        let mut arbiter = module("arbiter", &["navigation"]);
        arbiter.winner = Some("vff".into());
        let mut vff = module("vff", &["navigation", "behaviours"]);
        vff.behaviour = Some(BehaviourState::Winner);
        let mut stop = module("stop", &["navigation", "behaviours"]);
        stop.behaviour = Some(BehaviourState::Ready);
        let status = Status {
            system: "robot".into(),
            modules: vec![module("sim", &[]), arbiter, vff, stop],
            mission: Some(MissionStatus {
                marking: [("drive".to_owned(), 1)].into(),
                ..MissionStatus::default()
            }),
            ..Status::default()
        };
        let history = BTreeMap::new();
        let mut harness = egui_kittest::Harness::new_ui(|ui| {
            egui::ScrollArea::vertical().show(ui, |ui| {
                tree_ui(ui, &status, &history, true);
            });
        });
        harness.run();
        harness.get_by_label("system robot · place drive");
        harness.get_by_label("▣ navigation — in control: vff");
        harness.get_by_label("⚖ arbiter — in control: vff");
        harness.get_by_label("▣ behaviours · 2 modules");
        harness.get_by_label("★ vff in control");
        harness.get_by_label("stop: ready");
        harness.get_by_label("modules in no subsystem");
        // In that order, top to bottom: the place, the subsystem, the one inside, the rest.
        let top = |label: &str| harness.get_by_label(label).rect().top();
        assert!(top("system robot · place drive") < top("▣ navigation — in control: vff"));
        assert!(top("▣ navigation — in control: vff") < top("▣ behaviours · 2 modules"));
        assert!(top("▣ behaviours · 2 modules") < top("★ vff in control"));
        assert!(top("★ vff in control") < top("modules in no subsystem"));
    }
}
