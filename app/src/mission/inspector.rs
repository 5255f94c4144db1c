//! The properties of what is selected on the map: a waypoint's name and symbol, a leg's time
//! constraints, actions and contingencies, a graphic's kind and time, a unit's code, or (with
//! nothing selected) the plan's own settings. Every change is queued as one
//! [`PlanCommand::Change`]; what the user types stays as typed (a draft) until it reads right.

use std::collections::BTreeMap;

use armor_model::geo::LatLon;
use armor_model::net::{format_rfc3339, parse_rfc3339};
use armor_model::plan::{
    Action, ActionModule, ActionParam, Alternative, AreaKind, Contingency, GraphicKind, Leg, Plan,
    Response, Trigger,
};
use armor_model::world::Point;
use armor_module_api::describe::is_identifier;
use egui::{Color32, RichText, Ui};

use super::plan_edit::{PlanCommand, Selection};
use super::symbols;
use super::{LegRoute, MissionView};
use crate::common::palette::Catalog;

const ERROR: Color32 = Color32::from_rgb(230, 90, 70);

#[derive(Default)]
pub struct InspectorState {
    /// What is typed in each field, by field key, while it does not read right or until the
    /// selection changes.
    pub drafts: BTreeMap<String, String>,
    /// The module descriptions (the studio's palette): parameter names for actions.
    pub catalog: Catalog,
    /// The selection the drafts belong to.
    drafts_for: Selection,
}

/// One edit of the plan: a copy changed by `edit`, queued under `field`.
struct Edits<'a> {
    plan: &'a Plan,
    commands: Vec<PlanCommand>,
}

impl Edits<'_> {
    fn change(&mut self, field: &str, edit: impl FnOnce(&mut Plan)) {
        let mut plan = self.plan.clone();
        edit(&mut plan);
        if plan != *self.plan {
            self.commands.push(PlanCommand::Change {
                plan: Box::new(plan),
                field: field.to_owned(),
            });
        }
    }
}

/// A text field whose value is parsed: returns the new value when the text changed and reads
/// right; shows why when it does not.
fn parsed_field<T>(
    ui: &mut Ui,
    drafts: &mut BTreeMap<String, String>,
    label: &str,
    key: &str,
    current: String,
    hint: &str,
    parse: impl Fn(&str) -> Result<T, String>,
) -> Option<T> {
    let mut text = drafts.get(key).cloned().unwrap_or_else(|| current.clone());
    let mut result = None;
    ui.horizontal(|ui| {
        let label = ui.label(label);
        let response = ui
            .add(
                egui::TextEdit::singleline(&mut text)
                    .id_salt(key)
                    .hint_text(hint)
                    .desired_width(180.0),
            )
            .labelled_by(label.id);
        if response.changed() {
            drafts.insert(key.to_owned(), text.clone());
            if let Ok(value) = parse(text.trim()) {
                result = Some(value);
            }
        }
    });
    if drafts.contains_key(key)
        && let Err(why) = parse(text.trim())
    {
        ui.label(RichText::new(why).color(ERROR).small());
    }
    result
}

fn optional_secs(text: &str) -> Result<Option<f64>, String> {
    if text.is_empty() {
        return Ok(None);
    }
    match text.parse::<f64>() {
        Ok(secs) if secs.is_finite() && secs >= 0.0 => Ok(Some(secs)),
        _ => Err("a number of seconds, 0 or more (empty: none)".to_owned()),
    }
}

fn optional_date(text: &str) -> Result<Option<f64>, String> {
    if text.is_empty() {
        return Ok(None);
    }
    parse_rfc3339(text).map(Some)
}

fn show_secs(value: Option<f64>) -> String {
    value.map(|secs| secs.to_string()).unwrap_or_default()
}

fn show_date(value: Option<f64>) -> String {
    value.map(format_rfc3339).unwrap_or_default()
}

/// A new name for a waypoint, leg, graphic or unit: an identifier no other element has.
fn check_name(plan: &Plan, old: &str, new: &str) -> Result<String, String> {
    if !is_identifier(new) {
        return Err("a name is letters, digits and _ (not first a digit)".to_owned());
    }
    let taken = plan.waypoints.iter().any(|w| w.name == new)
        || plan.legs.iter().any(|l| l.name == new)
        || plan.graphics.iter().any(|g| g.name == new)
        || plan.units.iter().any(|u| u.name == new);
    if taken && new != old {
        return Err(format!(
            "`{new}` is already the name of something in the plan"
        ));
    }
    Ok(new.to_owned())
}

impl MissionView {
    pub fn set_catalog(&mut self, catalog: &Catalog) {
        if self.inspector.catalog != *catalog {
            self.inspector.catalog = catalog.clone();
            self.recheck(true);
        }
    }

    /// The right-hand panel: the selection's properties.
    pub fn inspector_ui(&mut self, ui: &mut Ui) {
        let selection = self.editor.selection.clone();
        if self.inspector.drafts_for != selection {
            self.inspector.drafts.clear();
            self.inspector.drafts_for = selection.clone();
        }
        let modules = self.surroundings.module_names();
        let origin = self.surroundings.origin(&self.editor.plan);
        let legs = &self.checked.legs;
        let mut edits = Edits {
            plan: &self.editor.plan,
            commands: Vec::new(),
        };
        let drafts = &mut self.inspector.drafts;
        let catalog = &self.inspector.catalog;
        let system = self.surroundings.system.as_ref();
        let type_of = |module: &str| {
            system.and_then(|system| {
                system
                    .modules
                    .iter()
                    .find(|m| m.name == module)
                    .map(|m| m.module_type.clone())
            })
        };
        let param_names = |module: &str| -> Vec<String> {
            type_of(module)
                .and_then(|module_type| catalog.get(&module_type))
                .map(|description| description.params.iter().map(|p| p.name.clone()).collect())
                .unwrap_or_default()
        };
        let height = ui.available_height() * 0.62;
        egui::ScrollArea::vertical()
            .id_salt("inspector")
            .max_height(height)
            .show(ui, |ui| match selection {
                Selection::Waypoint(name) => {
                    let Some(waypoint) = edits.plan.waypoint(&name).cloned() else {
                        return;
                    };
                    ui.heading(format!("Waypoint {name}"));
                    if let Some(new) =
                        parsed_field(ui, drafts, "Name", "wp-name", name.clone(), "", |t| {
                            check_name(edits.plan, &name, t)
                        })
                    {
                        edits.change("wp-name", |plan| rename_waypoint(plan, &name, &new));
                        drafts.clear();
                    }
                    let symbol = parsed_field(
                        ui,
                        drafts,
                        "Symbol (SIDC)",
                        "wp-symbol",
                        waypoint.symbol.clone().unwrap_or_default(),
                        "e.g. SFGPUCR----D---",
                        |t| match t {
                            "" => Ok(None),
                            code => symbols::parse(code).map(|_| Some(code.to_owned())),
                        },
                    );
                    if let Some(symbol) = symbol {
                        edits.change("wp-symbol", |plan| {
                            if let Some(w) = plan.waypoints.iter_mut().find(|w| w.name == name) {
                                w.symbol = symbol;
                            }
                        });
                    }
                    if let Some(Ok(symbol)) = waypoint.symbol.as_deref().map(symbols::parse) {
                        ui.label(RichText::new(symbol.describe()).weak());
                    }
                    position_fields(ui, drafts, &mut edits, &name, waypoint.position, origin);
                    ui.label(RichText::new("or drag it on the map").weak());
                }
                Selection::Leg(index) => {
                    let Some(leg) = edits.plan.legs.get(index).cloned() else {
                        return;
                    };
                    ui.heading(format!("Leg {}", leg.name));
                    ui.label(format!("from {} to {}", leg.from, leg.to));
                    leg_route_ui(ui, legs.get(index), edits.plan.navigation.speed_mps);
                    if let Some(new) =
                        parsed_field(ui, drafts, "Name", "leg-name", leg.name.clone(), "", |t| {
                            check_name(edits.plan, &leg.name, t)
                        })
                    {
                        edits.change("leg-name", |plan| plan.legs[index].name = new);
                    }
                    ui.separator();
                    ui.label(RichText::new("Time").strong());
                    if let Some(wait) = parsed_field(
                        ui,
                        drafts,
                        "Wait (s)",
                        "leg-wait",
                        show_secs(leg.wait_secs),
                        "stay at the destination",
                        optional_secs,
                    ) {
                        edits.change("leg-wait", |plan| plan.legs[index].wait_secs = wait);
                    }
                    if let Some(at) = parsed_field(
                        ui,
                        drafts,
                        "Not before",
                        "leg-net",
                        show_date(leg.not_before_unix_secs),
                        "2026-11-23T10:00:00Z",
                        optional_date,
                    ) {
                        edits.change("leg-net", |plan| plan.legs[index].not_before_unix_secs = at);
                    }
                    if let Some(at) = parsed_field(
                        ui,
                        drafts,
                        "Arrive by",
                        "leg-nlt",
                        show_date(leg.arrive_by_unix_secs),
                        "2026-11-23T10:05:00Z",
                        optional_date,
                    ) {
                        edits.change("leg-nlt", |plan| plan.legs[index].arrive_by_unix_secs = at);
                    }
                    ui.separator();
                    for (title, key, arrival) in [
                        ("While driving", "during", false),
                        ("On arrival", "arrival", true),
                    ] {
                        let action = if arrival { &leg.arrival } else { &leg.during };
                        let edited = action_ui(
                            ui,
                            drafts,
                            title,
                            key,
                            action.as_ref(),
                            arrival,
                            &modules,
                            &param_names,
                        );
                        if let Some(action) = edited {
                            edits.change(key, |plan| {
                                let leg = &mut plan.legs[index];
                                if arrival {
                                    leg.arrival = action;
                                } else {
                                    leg.during = action;
                                }
                            });
                        }
                    }
                    ui.separator();
                    ui.label(RichText::new("Contingencies").strong());
                    let waypoints: Vec<String> = edits
                        .plan
                        .waypoints
                        .iter()
                        .map(|w| w.name.clone())
                        .collect();
                    for trigger in triggers(&leg.contingencies) {
                        let current = leg
                            .contingencies
                            .iter()
                            .find(|c| same_slot(&c.trigger, &trigger))
                            .map(|c| c.response.clone());
                        let key = format!("leg-{}", trigger.describe());
                        if let Some(response) =
                            response_ui(ui, &key, &trigger, current, &waypoints, "as the plan says")
                        {
                            edits.change(&key, |plan| {
                                set_contingency(&mut plan.legs[index], trigger, response)
                            });
                        }
                    }
                    ui.separator();
                    if ui.button("Insert a waypoint in the middle").clicked() {
                        edits.commands.push(PlanCommand::InsertWaypoint(index));
                    }
                }
                Selection::Graphic(index) => {
                    let Some(graphic) = edits.plan.graphics.get(index).cloned() else {
                        return;
                    };
                    ui.heading(super::plan_edit::describe_graphic(&graphic));
                    if let Some(new) = parsed_field(
                        ui,
                        drafts,
                        "Name",
                        "g-name",
                        graphic.name.clone(),
                        "",
                        |t| check_name(edits.plan, &graphic.name, t),
                    ) {
                        edits.change("g-name", |plan| plan.graphics[index].name = new);
                    }
                    let mut kind = graphic.kind;
                    egui::ComboBox::from_label("Kind")
                        .selected_text(kind_label(kind))
                        .show_ui(ui, |ui| {
                            let is_area = matches!(kind, GraphicKind::Area(_));
                            let choices: Vec<GraphicKind> = if is_area {
                                AreaKind::ALL
                                    .iter()
                                    .map(|k| GraphicKind::Area(*k))
                                    .collect()
                            } else {
                                vec![GraphicKind::PhaseLine, GraphicKind::Boundary]
                            };
                            for choice in choices {
                                ui.selectable_value(&mut kind, choice, kind_label(choice));
                            }
                        });
                    if kind != graphic.kind {
                        edits.change("g-kind", |plan| plan.graphics[index].kind = kind);
                    }
                    if graphic.kind == GraphicKind::PhaseLine
                        && let Some(at) = parsed_field(
                            ui,
                            drafts,
                            "Cross at",
                            "g-at",
                            show_date(graphic.at_unix_secs),
                            "2026-11-23T10:03:00Z",
                            optional_date,
                        )
                    {
                        edits.change("g-at", |plan| plan.graphics[index].at_unix_secs = at);
                    }
                    ui.label(RichText::new("Drag the corners to reshape it.").weak());
                }
                Selection::Unit(index) => {
                    let Some(unit) = edits.plan.units.get(index).cloned() else {
                        return;
                    };
                    ui.heading(format!("Unit {}", unit.name));
                    if let Some(new) =
                        parsed_field(ui, drafts, "Name", "u-name", unit.name.clone(), "", |t| {
                            check_name(edits.plan, &unit.name, t)
                        })
                    {
                        edits.change("u-name", |plan| plan.units[index].name = new);
                    }
                    if let Some(code) =
                        parsed_field(ui, drafts, "SIDC", "u-sidc", unit.sidc.clone(), "", |t| {
                            symbols::parse(t).map(|_| t.to_owned())
                        })
                    {
                        edits.change("u-sidc", |plan| plan.units[index].sidc = code);
                    }
                    if let Ok(symbol) = symbols::parse(&unit.sidc) {
                        ui.label(RichText::new(symbol.describe()).weak());
                    }
                }
                Selection::None => plan_settings_ui(ui, drafts, &mut edits, &modules, &param_names),
            });
        self.commands.extend(edits.commands);
        ui.separator();
        self.check_ui(ui);
    }

    /// What the compiler and the verification say, in words; a click on a problem selects the
    /// leg it is about.
    fn check_ui(&mut self, ui: &mut Ui) {
        ui.heading("Check");
        egui::ScrollArea::vertical()
            .id_salt("check")
            .show(ui, |ui| {
                for problem in &self.surroundings.problems {
                    ui.add(egui::Label::new(RichText::new(problem).color(ERROR)).wrap());
                }
                let checked = &self.checked;
                if self.editor.plan.waypoints.is_empty() {
                    ui.label("Draw the route: choose the waypoint tool (W) and click the map.");
                } else if checked.errors.is_empty() && self.surroundings.problems.is_empty() {
                    let (colour, headline) = check_headline(checked.warnings.len());
                    ui.colored_label(colour, headline);
                }
                for line in checked.summary() {
                    ui.label(line);
                }
                for problem in &checked.errors {
                    ui.add(
                        egui::Label::new(
                            RichText::new(format!("{}: {}", problem.pos, problem.message))
                                .color(ERROR),
                        )
                        .wrap(),
                    );
                }
                for warning in &checked.warnings {
                    ui.add(
                        egui::Label::new(
                            RichText::new(format!("warning: {}", warning.message)).color(WARNING),
                        )
                        .wrap(),
                    );
                }
            });
    }
}

/// What the robot will drive on a leg: the planned path's length and the time it takes at the
/// plan's speed, or why there is no way through.
fn leg_route_ui(ui: &mut Ui, route: Option<&LegRoute>, speed_mps: f64) {
    match route {
        Some(LegRoute::Path { length_m, .. }) => {
            let time = if speed_mps > 0.0 {
                format!(", about {:.0} s at {speed_mps} m/s", length_m / speed_mps)
            } else {
                String::new()
            };
            ui.label(format!("path: {length_m:.1} m{time}"));
        }
        Some(LegRoute::Cut { why, .. }) => {
            ui.add(egui::Label::new(RichText::new(why).color(ERROR)).wrap());
        }
        Some(LegRoute::Unplaced) | None => {}
    }
}

/// A field of a waypoint's position: label, key, value, where the waypoint goes for a new
/// value, and how the text is read.
type PositionField<P> = (
    &'static str,
    &'static str,
    f64,
    Box<dyn Fn(f64) -> LatLon>,
    P,
);

/// A waypoint's position, editable as latitude and longitude (degrees) and as metres east and
/// north of the world's origin (the frame the sim and the planner use).
fn position_fields(
    ui: &mut Ui,
    drafts: &mut BTreeMap<String, String>,
    edits: &mut Edits,
    name: &str,
    at: LatLon,
    origin: LatLon,
) {
    let local = at.to_local(origin);
    let number = |range: std::ops::RangeInclusive<f64>, what: &'static str| {
        move |text: &str| match text.parse::<f64>() {
            Ok(value) if value.is_finite() && range.contains(&value) => Ok(value),
            _ => Err(format!(
                "{what}: a number from {} to {}",
                range.start(),
                range.end()
            )),
        }
    };
    let fields: [PositionField<_>; 4] = [
        (
            "Latitude (°)",
            "wp-lat",
            at.lat_deg,
            Box::new(move |lat| LatLon::new(lat, at.lon_deg)),
            number(-90.0..=90.0, "latitude"),
        ),
        (
            "Longitude (°)",
            "wp-lon",
            at.lon_deg,
            Box::new(move |lon| LatLon::new(at.lat_deg, lon)),
            number(-180.0..=180.0, "longitude"),
        ),
        (
            "East (m)",
            "wp-east",
            local.x,
            Box::new(move |x| LatLon::from_local(Point::new(x, local.y), origin)),
            number(-1e6..=1e6, "metres east"),
        ),
        (
            "North (m)",
            "wp-north",
            local.y,
            Box::new(move |y| LatLon::from_local(Point::new(local.x, y), origin)),
            number(-1e6..=1e6, "metres north"),
        ),
    ];
    for (label, key, current, place, parse) in fields {
        let shown = if key.ends_with("lat") || key.ends_with("lon") {
            format!("{current:.7}")
        } else {
            format!("{current:.2}")
        };
        if let Some(value) = parsed_field(ui, drafts, label, key, shown, "", parse) {
            let position = place(value);
            edits.change(key, |plan| {
                if let Some(w) = plan.waypoints.iter_mut().find(|w| w.name == name) {
                    w.position = position;
                }
            });
        }
    }
}

/// The check's headline for a plan without errors: green when nothing is to be said, amber
/// with the count when warnings follow (a late leg is not "no problems").
fn check_headline(warnings: usize) -> (Color32, String) {
    match warnings {
        0 => (
            Color32::from_rgb(90, 200, 110),
            "Ready to run: no problems".to_owned(),
        ),
        1 => (WARNING, "Ready to run, 1 warning".to_owned()),
        n => (WARNING, format!("Ready to run, {n} warnings")),
    }
}

const WARNING: Color32 = Color32::from_rgb(220, 160, 40);

fn plan_settings_ui(
    ui: &mut Ui,
    drafts: &mut BTreeMap<String, String>,
    edits: &mut Edits,
    modules: &[String],
    param_names: &dyn Fn(&str) -> Vec<String>,
) {
    let plan = edits.plan;
    ui.heading("Plan");
    ui.label(RichText::new("Select a waypoint, leg, graphic or unit to edit it.").weak());
    if let Some(name) = parsed_field(ui, drafts, "Name", "p-name", plan.name.clone(), "", |t| {
        if is_identifier(t) {
            Ok(t.to_owned())
        } else {
            Err("letters, digits and _".to_owned())
        }
    }) {
        edits.change("p-name", |plan| plan.name = name);
    }
    if let Some(system) = parsed_field(
        ui,
        drafts,
        "System file",
        "p-system",
        plan.system.clone(),
        "relative to the plan",
        |t| {
            if t.is_empty() {
                Err("the system the plan runs on".to_owned())
            } else {
                Ok(t.to_owned())
            }
        },
    ) {
        edits.change("p-system", |plan| plan.system = system);
    }
    if let Some(world) = parsed_field(
        ui,
        drafts,
        "World",
        "p-world",
        plan.world.clone(),
        "the simulator's",
        |t| Ok::<_, String>(t.to_owned()),
    ) {
        edits.change("p-world", |plan| plan.world = world);
    }
    if let Some(start) = parsed_field(
        ui,
        drafts,
        "Start",
        "p-start",
        show_date(plan.start_unix_secs),
        "2026-11-23T10:00:00Z",
        optional_date,
    ) {
        edits.change("p-start", |plan| plan.start_unix_secs = start);
    }
    if let Some(speed) = parsed_field(
        ui,
        drafts,
        "Speed (m/s)",
        "p-speed",
        plan.navigation.speed_mps.to_string(),
        "",
        |t| match t.parse::<f64>() {
            Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
            _ => Err("a speed above 0".to_owned()),
        },
    ) {
        edits.change("p-speed", |plan| plan.navigation.speed_mps = speed);
    }
    let companions = plan.navigation.companions.join(", ");
    if let Some(list) = parsed_field(
        ui,
        drafts,
        "Drives with",
        "p-companions",
        companions,
        "modules beside the navigation, e.g. avoider",
        |t| {
            let names: Vec<String> = t
                .split(',')
                .map(str::trim)
                .filter(|n| !n.is_empty())
                .map(str::to_owned)
                .collect();
            match names.iter().find(|name| !modules.contains(name)) {
                Some(name) => Err(format!("`{name}` is not a module of the system")),
                None => Ok(names),
            }
        },
    ) {
        edits.change("p-companions", |plan| plan.navigation.companions = list);
    }
    ui.separator();
    ui.label(RichText::new("Contingencies of every leg").strong());
    let waypoints: Vec<String> = plan.waypoints.iter().map(|w| w.name.clone()).collect();
    for trigger in triggers(&plan.contingencies) {
        let current = plan
            .contingencies
            .iter()
            .find(|c| same_slot(&c.trigger, &trigger))
            .map(|c| c.response.clone());
        let key = format!("p-{}", trigger.describe());
        // Blocked or late with no response stops the mission; lost with none has no effect.
        let unset = match trigger {
            Trigger::Lost { .. } => "drive on regardless",
            _ => "stop the mission",
        };
        if let Some(response) = response_ui(ui, &key, &trigger, current, &waypoints, unset) {
            edits.change(&key, |plan| {
                plan.contingencies
                    .retain(|c| !same_slot(&c.trigger, &trigger));
                if let Some(response) = response {
                    plan.contingencies.push(Contingency {
                        trigger,
                        response,
                        pos: Default::default(),
                    });
                }
            });
        }
    }
    ui.separator();
    let throughout = plan.throughout.clone();
    if let Some(action) = action_ui(
        ui,
        drafts,
        "Throughout (a recorder)",
        "throughout",
        throughout.as_ref(),
        false,
        modules,
        param_names,
    ) {
        edits.change("throughout", |plan| plan.throughout = action);
    }
}

fn kind_label(kind: GraphicKind) -> &'static str {
    match kind {
        GraphicKind::PhaseLine => "phase line",
        GraphicKind::Boundary => "boundary",
        GraphicKind::Area(kind) => kind.as_str(),
    }
}

fn rename_waypoint(plan: &mut Plan, old: &str, new: &str) {
    for waypoint in plan.waypoints.iter_mut().filter(|w| w.name == old) {
        waypoint.name = new.to_owned();
    }
    for leg in &mut plan.legs {
        for end in [&mut leg.from, &mut leg.to] {
            if end == old {
                *end = new.to_owned();
            }
        }
    }
    for contingency in plan.contingencies_mut() {
        if let Response::Return { waypoint } = &mut contingency.response
            && waypoint == old
        {
            *waypoint = new.to_owned();
        }
    }
}

/// The triggers the inspector offers a response to, in this order: `blocked`, `late`, and
/// `lost` of the localiser the contingencies already name (else the bundled systems'
/// `localiser`). A module's `failed` is written in the plan file.
fn triggers(contingencies: &[Contingency]) -> [Trigger; 3] {
    let localiser = contingencies
        .iter()
        .find_map(|c| match &c.trigger {
            Trigger::Lost { module } => Some(module.clone()),
            _ => None,
        })
        .unwrap_or_else(|| armor_model::plan::DEFAULT_LOCALISER.to_owned());
    [
        Trigger::Blocked,
        Trigger::Late,
        Trigger::Lost { module: localiser },
    ]
}

/// Whether two triggers take the same place in the inspector: equal, or both `lost` (a plan
/// listens to one localiser).
fn same_slot(a: &Trigger, b: &Trigger) -> bool {
    matches!((a, b), (Trigger::Lost { .. }, Trigger::Lost { .. })) || a == b
}

fn set_contingency(leg: &mut Leg, trigger: Trigger, response: Option<Response>) {
    leg.contingencies
        .retain(|c| !same_slot(&c.trigger, &trigger));
    if let Some(response) = response {
        leg.contingencies.push(Contingency {
            trigger,
            response,
            pos: Default::default(),
        });
    }
}

/// A choice of response to `trigger`; `None` inside the result means "not set here".
fn response_ui(
    ui: &mut Ui,
    key: &str,
    trigger: &Trigger,
    current: Option<Response>,
    waypoints: &[String],
    unset: &str,
) -> Option<Option<Response>> {
    let describe = |response: &Option<Response>| match response {
        None => unset.to_owned(),
        Some(Response::Skip) => "skip the rest of the leg".to_owned(),
        Some(Response::Hold) => "hold for the operator".to_owned(),
        Some(Response::Continue) => "continue".to_owned(),
        Some(Response::Repair { after_secs: None }) => "repair (the run's best option)".to_owned(),
        Some(Response::Repair {
            after_secs: Some(after_secs),
        }) => format!("repair (the run's best option after {after_secs} s)"),
        Some(Response::Return { waypoint }) => format!("return to {waypoint}"),
    };
    let mut choice = current.clone();
    let mut choices = vec![None, Some(Response::Skip), Some(Response::Hold)];
    if *trigger == Trigger::Late {
        choices.push(Some(Response::Continue));
    }
    // A robot that does not know where it is cannot drive back anywhere (the plan's reader
    // refuses `return` on `lost`): hold or skip only.
    if !matches!(trigger, Trigger::Lost { .. }) {
        choices.extend(waypoints.iter().map(|w| {
            Some(Response::Return {
                waypoint: w.clone(),
            })
        }));
    }
    egui::ComboBox::new(key, format!("when {}", trigger.describe()))
        .selected_text(describe(&choice))
        .show_ui(ui, |ui| {
            for option in choices {
                let label = describe(&option);
                ui.selectable_value(&mut choice, option, label);
            }
        });
    (choice != current).then_some(choice)
}

/// An action's modules and their parameters; on arrival, also what ends it; then, for a leg's
/// (any `key` but `throughout`), its alternatives. Returns the new action (`None` inside: no action) when it changed.
#[allow(clippy::too_many_arguments)]
fn action_ui(
    ui: &mut Ui,
    drafts: &mut BTreeMap<String, String>,
    title: &str,
    key: &str,
    action: Option<&Action>,
    arrival: bool,
    modules: &[String],
    param_names: &dyn Fn(&str) -> Vec<String>,
) -> Option<Option<Action>> {
    let mut edited = action.cloned().unwrap_or_default();
    let before = edited.clone();
    ui.label(RichText::new(title).strong());
    modules_ui(ui, key, &mut edited.modules, modules, param_names);
    if arrival && !edited.modules.is_empty() {
        if let Some(until) = parsed_field(
            ui,
            drafts,
            "Until event",
            &format!("{key}-until"),
            edited.until.clone().unwrap_or_default(),
            "MODULE.EVENT",
            |t| match t {
                "" => Ok(None),
                event
                    if event
                        .split_once('.')
                        .is_some_and(|(m, e)| is_identifier(m) && is_identifier(e)) =>
                {
                    Ok(Some(event.to_owned()))
                }
                _ => Err("an event is MODULE.EVENT".to_owned()),
            },
        ) {
            edited.until = until;
        }
        if let Some(secs) = parsed_field(
            ui,
            drafts,
            "For at most (s)",
            &format!("{key}-for"),
            show_secs(edited.for_secs),
            "",
            optional_secs,
        ) {
            edited.for_secs = secs;
        }
    }
    // What runs throughout the mission has no leg to switch within.
    if !edited.modules.is_empty() && key != "throughout" {
        alternatives_ui(ui, drafts, key, &mut edited, modules, param_names);
    }
    if edited == before {
        return None;
    }
    Some((!edited.modules.is_empty()).then_some(edited))
}

/// A list of modules with their parameters: each removed or given a parameter, others added.
fn modules_ui(
    ui: &mut Ui,
    key: &str,
    list: &mut Vec<ActionModule>,
    modules: &[String],
    param_names: &dyn Fn(&str) -> Vec<String>,
) {
    let mut remove = None;
    for (m, module) in list.iter_mut().enumerate() {
        ui.horizontal(|ui| {
            ui.label(RichText::new(&module.name).monospace());
            if ui.small_button("remove").clicked() {
                remove = Some(m);
            }
        });
        let names = param_names(&module.name);
        let mut drop_param = None;
        for (p, param) in module.params.iter_mut().enumerate() {
            ui.horizontal(|ui| {
                ui.label(format!("  {}", param.name));
                ui.add(
                    egui::TextEdit::singleline(&mut param.value)
                        .id_salt((key, m, p))
                        .desired_width(120.0),
                );
                if ui.small_button("×").clicked() {
                    drop_param = Some(p);
                }
            });
        }
        if let Some(p) = drop_param {
            module.params.remove(p);
        }
        let unset: Vec<&String> = names
            .iter()
            .filter(|name| !module.params.iter().any(|p| &&p.name == name))
            .collect();
        if !unset.is_empty() {
            egui::ComboBox::new((key, m, "param"), "")
                .selected_text("set a parameter…")
                .show_ui(ui, |ui| {
                    for name in unset {
                        if ui.selectable_label(false, name.as_str()).clicked() {
                            module.params.push(ActionParam {
                                name: name.clone(),
                                ..ActionParam::default()
                            });
                        }
                    }
                });
        }
    }
    if let Some(m) = remove {
        list.remove(m);
    }
    let addable: Vec<&String> = modules
        .iter()
        .filter(|name| !list.iter().any(|m| &&m.name == name))
        .collect();
    egui::ComboBox::new((key, "add"), "")
        .selected_text("add a module…")
        .show_ui(ui, |ui| {
            for name in addable {
                if ui.selectable_label(false, name.as_str()).clicked() {
                    list.push(ActionModule {
                        name: name.clone(),
                        ..ActionModule::default()
                    });
                }
            }
        });
}

/// What an `on` field reads as: module names between spaces, each once; empty: the default.
fn parse_on(text: &str) -> Result<Vec<String>, String> {
    let mut names: Vec<String> = Vec::new();
    for word in text.split_whitespace() {
        if !is_identifier(word) {
            return Err(format!("`{word}` is not a module name"));
        }
        if !names.iter().any(|name| name == word) {
            names.push(word.to_owned());
        }
    }
    Ok(names)
}

/// An action's alternatives, in the order they are tried: each named, with the failures it
/// answers and its modules; moved earlier or later, removed, or added.
fn alternatives_ui(
    ui: &mut Ui,
    drafts: &mut BTreeMap<String, String>,
    key: &str,
    action: &mut Action,
    modules: &[String],
    param_names: &dyn Fn(&str) -> Vec<String>,
) {
    let answers: Vec<Vec<String>> = action
        .strategies()
        .into_iter()
        .skip(1)
        .map(|way| way.answers)
        .collect();
    let count = action.alternatives.len();
    let mut moved = None;
    let mut removed = None;
    for (i, alternative) in action.alternatives.iter_mut().enumerate() {
        let alt_key = format!("{key}-alt{i}");
        ui.add_space(4.0);
        ui.horizontal(|ui| {
            ui.label(RichText::new(format!("Alternative {}", i + 1)).strong());
            if ui
                .add_enabled(i > 0, egui::Button::new("earlier").small())
                .on_hover_text("Try it before the alternative above it")
                .clicked()
            {
                moved = Some((i, i - 1));
            }
            if ui
                .add_enabled(i + 1 < count, egui::Button::new("later").small())
                .on_hover_text("Try it after the alternative below it")
                .clicked()
            {
                moved = Some((i, i + 1));
            }
            if ui.small_button("remove").clicked() {
                removed = Some(i);
            }
        });
        if let Some(name) = parsed_field(
            ui,
            drafts,
            "Name",
            &format!("{alt_key}-name"),
            alternative.name.clone(),
            "alt1",
            |t| {
                if is_identifier(t) {
                    Ok(t.to_owned())
                } else {
                    Err("a name of letters, digits, `_` or `-`".to_owned())
                }
            },
        ) {
            alternative.name = name;
        }
        let answered = answers.get(i).cloned().unwrap_or_default();
        if let Some(on) = parsed_field(
            ui,
            drafts,
            "On failure of",
            &format!("{alt_key}-on"),
            alternative.on.join(" "),
            &answered.join(" "),
            parse_on,
        ) {
            alternative.on = on;
        }
        if answered.is_empty() {
            ui.colored_label(
                ERROR,
                "answers no failure: name modules above, or remove a module it does without",
            );
        } else {
            ui.weak(format!(
                "taken when {} fails for good",
                answered
                    .iter()
                    .map(|name| format!("`{name}`"))
                    .collect::<Vec<_>>()
                    .join(" or ")
            ));
        }
        modules_ui(ui, &alt_key, &mut alternative.modules, modules, param_names);
        if alternative.modules.is_empty() {
            ui.weak("runs none of the action's modules");
        }
    }
    let mut forget_drafts = || drafts.retain(|field, _| !field.starts_with(&format!("{key}-alt")));
    if let Some((from, to)) = moved {
        action.alternatives.swap(from, to);
        forget_drafts();
    }
    if let Some(i) = removed {
        action.alternatives.remove(i);
        forget_drafts();
    }
    ui.add_space(2.0);
    if ui
        .button("add an alternative")
        .on_hover_text(
            "Another way of doing it, tried when a module the way before it depends on fails \
             for good",
        )
        .clicked()
    {
        let taken = |name: &str| action.alternatives.iter().any(|a| a.name == name);
        let mut index = action.alternatives.len();
        while taken(&Alternative::default_name(index)) {
            index += 1;
        }
        action.alternatives.push(Alternative {
            name: Alternative::default_name(index),
            ..Alternative::default()
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_headline_counts_the_warnings() {
        assert_eq!(check_headline(0).1, "Ready to run: no problems");
        assert_eq!(
            check_headline(1),
            (WARNING, "Ready to run, 1 warning".to_owned())
        );
        assert_eq!(check_headline(3).1, "Ready to run, 3 warnings");
    }
}
