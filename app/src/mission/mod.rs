//! The Mission view: a plan drawn on a map of the world the robot runs in, compiled into its
//! Petri net as it is edited, with the net beside the map.
//!
//! - [`plan_edit`]: the editing session over a plan (selection, undo, the route's rules);
//! - [`tiles`]: the offline map, tiles rendered from the world with tiny-skia;
//! - [`symbols`]: APP-6 / MIL-STD-2525 unit symbols from SIDC codes;
//! - [`map`]: the plan drawn over the map and the clicks and drags that edit it;
//! - [`inspector`]: the properties of what is selected;
//! - [`net_view`]: the compiled net, laid out, linked to the map's selection.
//!
//! This file holds the view's state, what derives from the plan (its system, its world, the
//! compiled net and its verification) and the files: plans, GPX, mission XML, PNML.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use anyhow::Context as _;
use armor_model::SystemConfig;
use armor_model::net::{self, Analysis, MissionNet};
use armor_model::plan::{self, Compiled, LatLon, Origin, Plan};
use armor_model::world::World;
use armor_module_api::xml::Located;

use crate::command::UiCommand;
use crate::common::palette::Catalog;
use plan_edit::{Outcome, PlanCommand, PlanEditor, Selection};

pub mod basemap;
pub mod inspector;
pub mod map;
pub mod net_view;
pub mod plan_edit;
pub mod symbols;
pub mod tiles;

/// What a watched map's labels are placed with: the Run view gives it (the robots).
pub use map::Beside;

/// Reachable markings explored when a plan's net is verified (as `armor check` does).
const ANALYSIS_LIMIT_STATES: usize = 200_000;

/// What a click on the map does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tool {
    /// Select and drag what is on the map.
    Select,
    /// Add a waypoint at the end of the route.
    Waypoint,
    /// Draw a tactical graphic, corner by corner (double-click or Enter ends it).
    Graphic(plan::GraphicKind),
    /// Place a unit symbol.
    Unit,
}

impl Tool {
    /// The toolbar's tools, in order.
    pub const ALL: [Tool; 7] = [
        Tool::Select,
        Tool::Waypoint,
        Tool::Graphic(plan::GraphicKind::PhaseLine),
        Tool::Graphic(plan::GraphicKind::Boundary),
        Tool::Graphic(plan::GraphicKind::Area(plan::AreaKind::NoGo)),
        Tool::Graphic(plan::GraphicKind::Area(plan::AreaKind::Objective)),
        Tool::Unit,
    ];

    /// The toolbar's label.
    pub fn label(self) -> &'static str {
        match self {
            Tool::Select => "Select (V)",
            Tool::Waypoint => "Waypoint (W)",
            Tool::Graphic(plan::GraphicKind::PhaseLine) => "Phase line (P)",
            Tool::Graphic(plan::GraphicKind::Boundary) => "Boundary (B)",
            Tool::Graphic(plan::GraphicKind::Area(plan::AreaKind::NoGo)) => "No-go area (N)",
            Tool::Graphic(plan::GraphicKind::Area(plan::AreaKind::Objective)) => "Objective",
            Tool::Graphic(plan::GraphicKind::Area(_)) => "Area",
            Tool::Unit => "Unit (U)",
        }
    }

    /// What it does, for the toolbar's hint and the status line.
    pub fn help(self) -> &'static str {
        match self {
            Tool::Select => "select tool: click to select, drag to move, right-click for more",
            Tool::Waypoint => "waypoint tool: click the map to add a waypoint at the route's end",
            Tool::Graphic(plan::GraphicKind::Area(_)) => {
                "area tool: click its corners, double-click or Enter to end, Escape to drop"
            }
            Tool::Graphic(_) => {
                "line tool: click its points, double-click or Enter to end, Escape to drop"
            }
            Tool::Unit => "unit tool: click the map to place the unit symbol of the code beside",
        }
    }
}

/// The keys that choose a tool on the map.
pub const TOOL_KEYS: &[(egui::Key, Tool)] = &[
    (egui::Key::V, Tool::Select),
    (egui::Key::W, Tool::Waypoint),
    (egui::Key::P, Tool::Graphic(plan::GraphicKind::PhaseLine)),
    (egui::Key::B, Tool::Graphic(plan::GraphicKind::Boundary)),
    (
        egui::Key::N,
        Tool::Graphic(plan::GraphicKind::Area(plan::AreaKind::NoGo)),
    ),
    (egui::Key::U, Tool::Unit),
];

impl MissionView {
    /// Does a command of the table that edits the plan or moves about the map (the window does
    /// the files').
    pub fn execute(&mut self, command: UiCommand) {
        match command {
            UiCommand::Undo => self.commands.push(PlanCommand::Undo),
            UiCommand::Redo => self.commands.push(PlanCommand::Redo),
            UiCommand::Delete => self.commands.push(PlanCommand::DeleteSelection),
            UiCommand::ClearSelection if self.map.pending.is_empty() => {
                self.set_tool(Tool::Select);
                self.commands.push(PlanCommand::Select(Selection::None));
            }
            // Home fits what the pointer is over: the net or the map.
            UiCommand::ZoomToFit if self.net_view.pointer_over => {
                self.net_view.fit_pending = true;
                self.net_view.fit_whole = true;
            }
            UiCommand::ZoomToFit => self.map.fit_requested = true,
            _ => {}
        }
    }

    /// The tool whose key (in [`TOOL_KEYS`]) was pressed this frame, now chosen.
    pub fn tool_key_input(&mut self, ctx: &egui::Context) -> Option<Tool> {
        let mut chosen = None;
        for (key, tool) in TOOL_KEYS {
            let shortcut = egui::KeyboardShortcut::new(egui::Modifiers::NONE, *key);
            if ctx.input_mut(|input| input.consume_shortcut(&shortcut)) {
                self.set_tool(*tool);
                chosen = Some(*tool);
            }
        }
        chosen
    }
}

/// The plan's surroundings: its system and its world, read from the files it names.
#[derive(Clone, Debug, Default)]
pub struct PlanSurroundings {
    /// The folder the plan's relative paths start from.
    pub base: PathBuf,
    pub system_file: PathBuf,
    pub system: Option<SystemConfig>,
    pub world: Option<World>,
    /// Where the plan's base map (`<basemap href>`) is, when it opens.
    pub basemap: Option<PathBuf>,
    /// Why the system or the world could not be read.
    pub problems: Vec<String>,
    /// What they were read for: (base, system, world, base map) of the plan.
    key: (PathBuf, String, String, String),
}

impl PlanSurroundings {
    fn load(plan: &Plan, base: &Path) -> PlanSurroundings {
        let system_file = base.join(&plan.system);
        let mut problems = Vec::new();
        let system = if plan.system.is_empty() {
            problems.push("the plan names no system file (set it with nothing selected)".into());
            None
        } else {
            match std::fs::read_to_string(&system_file) {
                Err(err) => {
                    problems.push(format!("cannot read {}: {err}", system_file.display()));
                    None
                }
                Ok(text) => match SystemConfig::parse(&text) {
                    Ok(system) => Some(system),
                    Err(errors) => {
                        problems.extend(errors.iter().map(|err| {
                            format!("{}:{}: {}", system_file.display(), err.pos, err.message)
                        }));
                        None
                    }
                },
            }
        };
        let world = system.as_ref().and_then(|system| {
            let system_dir = system_file.parent().unwrap_or(base);
            let module_path = armor_runtime::probe::module_path();
            armor_runtime::mission::plan_world(plan, system, base, system_dir, &module_path)
                .map_err(|err| problems.push(err))
                .ok()
                .flatten()
        });
        let basemap = plan.basemap.as_ref().and_then(|basemap| {
            let module_path = armor_runtime::probe::module_path();
            armor_runtime::mission::plan_basemap(&basemap.href, base, &module_path)
                .map(|map| map.path().to_path_buf())
                .map_err(|err| problems.push(err))
                .ok()
        });
        PlanSurroundings {
            base: base.to_path_buf(),
            system_file,
            system,
            world,
            basemap,
            problems,
            key: key_of(plan, base),
        }
    }

    /// The geographic point of the frame's (0, 0): the world's, else the plan's own.
    pub fn origin(&self, plan: &Plan) -> LatLon {
        match &self.world {
            Some(world) => {
                let (lat, lon) = world.origin_lat_lon();
                LatLon::new(lat, lon)
            }
            None => plan.origin.unwrap_or_default(),
        }
    }

    /// The instances of the system, by name.
    pub fn module_names(&self) -> Vec<String> {
        self.system
            .iter()
            .flat_map(|system| system.modules.iter().map(|m| m.name.clone()))
            .collect()
    }
}

fn key_of(plan: &Plan, base: &Path) -> (PathBuf, String, String, String) {
    let basemap = plan.basemap.as_ref().map(|basemap| basemap.href.clone());
    (
        base.to_path_buf(),
        plan.system.clone(),
        plan.world.clone(),
        basemap.unwrap_or_default(),
    )
}

/// The plan compiled and verified.
#[derive(Clone, Debug, Default)]
pub struct Checked {
    pub compiled: Option<Compiled>,
    pub analysis: Option<Analysis>,
    /// What keeps the plan from compiling or running, as `armor check` says it.
    pub errors: Vec<Located>,
    /// What may keep it from going as drawn (time constraints).
    pub warnings: Vec<Located>,
    /// Each leg as the robot will drive it (the planned path), or why it cannot.
    pub legs: Vec<LegRoute>,
}

/// A leg on the map.
#[derive(Clone, Debug, PartialEq)]
pub enum LegRoute {
    /// The path planned round obstacles and no-go areas, in the world frame.
    Path {
        points: Vec<armor_model::world::Point>,
        length_m: f64,
    },
    /// No way through for the robot: why, and where the way is narrowest.
    Cut {
        why: String,
        at: Option<armor_model::world::Point>,
    },
    /// One of its ends is not placed (reported on its own).
    Unplaced,
}

impl Checked {
    fn of(plan: &Plan, surroundings: &PlanSurroundings, catalog: &Catalog) -> Checked {
        let mut checked = Checked::default();
        if plan.waypoints.is_empty() {
            return checked;
        }
        // The robot `armor check` plans for: the plan's, else its system's modules'.
        let robot = plan::robot(plan, surroundings.system.as_ref(), catalog);
        match plan::compile_for(plan, surroundings.world.as_ref(), &robot) {
            Err(problems) => {
                checked.errors = problems;
                // The legs that have a path are still drawn along it, the others as cut.
                let legs = plan::plan_legs(plan, surroundings.world.as_ref(), &robot);
                checked.legs = legs
                    .paths
                    .into_iter()
                    .map(|path| match path {
                        Some(Ok(path)) => LegRoute::Path {
                            length_m: path.length_m,
                            points: path.points,
                        },
                        Some(Err(why)) => LegRoute::Cut {
                            at: match &why {
                                armor_model::planner::PathError::Cut(bottleneck) => {
                                    Some(bottleneck.at)
                                }
                                armor_model::planner::PathError::Blocked { at, .. } => Some(*at),
                            },
                            why: why.to_string(),
                        },
                        None => LegRoute::Unplaced,
                    })
                    .collect();
            }
            Ok(compiled) => {
                checked.legs = compiled
                    .routes
                    .iter()
                    .map(|points| LegRoute::Path {
                        length_m: armor_model::geo::path_length(points),
                        points: points.clone(),
                    })
                    .collect();
                if let Some(system) = &surroundings.system {
                    // Only the module types the palette knows can be checked; the others are
                    // the diagram's to report.
                    let known = system
                        .modules
                        .iter()
                        .all(|module| catalog.contains_key(&module.module_type));
                    if known {
                        checked.errors = net::check_names(&compiled.net, system, catalog);
                    }
                }
                let analysis = net::analyse(&compiled.net, ANALYSIS_LIMIT_STATES);
                checked.errors.extend(analysis.problems(&compiled.net));
                checked.warnings = compiled.warnings.clone();
                checked.analysis = Some(analysis);
                checked.compiled = Some(compiled);
            }
        }
        checked
    }

    pub fn net(&self) -> Option<&MissionNet> {
        self.compiled.as_ref().map(|compiled| &compiled.net)
    }

    /// Why `plan` has no net, for the net panel: what to draw when it has no route yet, else
    /// what keeps it from compiling, each blocked leg named with what blocks it.
    pub fn no_net_reasons(&self, plan: &Plan) -> (String, Vec<String>) {
        if plan.legs.is_empty() {
            return (
                "No net yet: draw a route of at least two waypoints on the map.".to_owned(),
                Vec::new(),
            );
        }
        let mut reasons = Vec::new();
        let mut said = BTreeSet::new();
        for (leg, route) in plan.legs.iter().zip(&self.legs) {
            let named = format!("leg `{}` ({} → {}) is blocked", leg.name, leg.from, leg.to);
            match route {
                LegRoute::Path { .. } => {}
                LegRoute::Cut { why, .. } => reasons.push(format!("{named}: {why}")),
                // An end that cannot be placed (off the world, in a no-go area) is what
                // `armor check` reports of that waypoint.
                LegRoute::Unplaced => {
                    for (index, error) in self.errors.iter().enumerate() {
                        let about_an_end = [&leg.from, &leg.to]
                            .iter()
                            .any(|end| error.message.contains(&format!("`{end}`")));
                        if about_an_end {
                            reasons.push(format!("{named}: {}", error.message));
                            said.insert(index);
                        }
                    }
                }
            }
        }
        // Then what `armor check` says besides.
        reasons.extend(
            self.errors
                .iter()
                .enumerate()
                .filter(|(index, _)| !said.contains(index))
                .map(|(_, error)| error.message.clone()),
        );
        (
            "No net: the plan does not compile. Once this is fixed, the net is drawn:".to_owned(),
            reasons,
        )
    }

    /// The verification in words.
    pub fn summary(&self) -> Vec<String> {
        let (Some(compiled), Some(analysis)) = (&self.compiled, &self.analysis) else {
            return Vec::new();
        };
        let net = &compiled.net;
        let mut lines = vec![format!(
            "{} places, {} transitions, {} reachable states{}",
            net.places.len(),
            net.transitions.len(),
            analysis.states,
            if analysis.truncated {
                " (stopped at the limit)"
            } else {
                ""
            }
        )];
        lines.push(match analysis.dead_count {
            0 if !analysis.truncated => {
                "no deadlock: every run ends in a final place or goes on".to_owned()
            }
            0 => "no deadlock among the states explored".to_owned(),
            n => format!("{n} deadlock(s): the mission can get stuck (see the problems)"),
        });
        lines.push(match analysis.never_fired.len() {
            0 => "every transition can fire".to_owned(),
            n => format!(
                "{n} transition(s) can never fire: {}",
                analysis.never_fired.join(", ")
            ),
        });
        lines
    }
}

/// The net panel's least height: its header and a few rows of the net.
const NET_PANEL_MIN: f32 = 150.0;

/// What a file operation of the view reports: the status line's text.
pub type Report = anyhow::Result<String>;

pub struct MissionView {
    pub editor: PlanEditor,
    path: Option<PathBuf>,
    /// The plan as last opened or saved.
    saved: Plan,
    pub surroundings: PlanSurroundings,
    checked: Checked,
    checked_revision: Option<u64>,
    pub(crate) commands: Vec<PlanCommand>,
    pub(crate) map: map::MapState,
    pub(crate) inspector: inspector::InspectorState,
    /// The net laid out, made again (names measured) at the next frame after the net changed.
    net_layout: Option<net_view::Layout>,
    /// How the net view is zoomed, panned and sized.
    pub(crate) net_view: net_view::NetViewState,
    /// The run's marking the net was last scrolled to.
    net_scrolled_for_marking: Option<armor_model::net::Marking>,
    /// The selection the net view last scrolled to.
    net_scrolled_for: Option<Selection>,
    /// The plan a run plays, which the Run view draws in place of the one edited (the operator
    /// may be editing ahead of the robot): see [`MissionView::watch_plan`].
    watched: Option<Watched>,
    /// The net drawn last was the run's ([`MissionView::marking_ui`]), not the edited plan's.
    net_drawn_watched: bool,
    /// The net panel has been shown at the net's own size once (the map framed again then).
    net_panel_sized: bool,
    /// The net was enlarged at the last frame (the map is framed again when this changes).
    net_was_enlarged: bool,
}

/// The plan a run plays, compiled as the Mission view compiles the plan edited.
struct Watched {
    /// Its text as the studio writes a plan: what tells one plan from another (two parses of
    /// one text differ by their positions in it).
    xml: String,
    plan: Plan,
    checked: Checked,
    layout: Option<net_view::Layout>,
}

impl MissionView {
    pub fn new(ctx: &egui::Context) -> MissionView {
        let mut view = MissionView {
            editor: PlanEditor::default(),
            path: None,
            saved: Plan::default(),
            surroundings: PlanSurroundings::default(),
            checked: Checked::default(),
            checked_revision: None,
            commands: Vec::new(),
            map: map::MapState::new(ctx),
            inspector: inspector::InspectorState::default(),
            net_layout: None,
            net_view: net_view::NetViewState::default(),
            net_scrolled_for_marking: None,
            net_scrolled_for: None,
            watched: None,
            net_drawn_watched: false,
            net_panel_sized: false,
            net_was_enlarged: false,
        };
        view.refresh_surroundings(true);
        view
    }

    // ----- What the window, tests and the bench read -----

    pub fn plan(&self) -> &Plan {
        &self.editor.plan
    }

    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    pub fn is_dirty(&self) -> bool {
        self.editor.plan != self.saved
    }

    pub fn checked(&self) -> &Checked {
        &self.checked
    }

    /// Draws `plan` (with its text as [`Plan::to_xml`] writes it) in the Run view, its map
    /// and its net with the run's marking, in place of the plan edited: the plan a run plays,
    /// which the operator may edit ahead of the robot before sending it. `None`: the Run view
    /// draws the plan edited. Compiled again only when it changed.
    pub fn watch_plan(&mut self, plan: Option<(&Plan, &str)>) {
        let Some((plan, xml)) = plan else {
            self.watched = None;
            return;
        };
        if self
            .watched
            .as_ref()
            .is_some_and(|watched| watched.xml == xml)
        {
            return;
        }
        let edited_is_it = self.checked_revision == Some(self.editor.revision())
            && self.editor.plan.to_xml() == xml;
        let checked = if edited_is_it {
            self.checked.clone()
        } else {
            Checked::of(plan, &self.surroundings, &self.inspector.catalog)
        };
        self.watched = Some(Watched {
            xml: xml.to_owned(),
            plan: plan.clone(),
            checked,
            layout: None,
        });
        self.net_view.fit_pending = true;
    }

    /// The plan the Run view draws: the run's ([`Self::watch_plan`]), else the one edited.
    pub fn watched_plan(&self) -> &Plan {
        self.watched
            .as_ref()
            .map_or(&self.editor.plan, |watched| &watched.plan)
    }

    /// [`Self::watched_plan`] compiled and verified.
    pub fn watched_checked(&self) -> &Checked {
        self.watched
            .as_ref()
            .map_or(&self.checked, |watched| &watched.checked)
    }

    /// Replaces the plan edited with `plan` as an edit (undone by Undo): the robot's plan,
    /// taken back over the operator's edits, or followed when there were none. `what` names
    /// the change in the undo history. Applied at once, not after the Mission view's next
    /// frame: the Run view, shown meanwhile, compares the plan edited with the robot's.
    pub fn take_plan(&mut self, plan: Plan, what: &str) {
        self.commands.push(PlanCommand::Change {
            plan: Box::new(plan),
            field: what.to_owned(),
        });
        self.apply_commands();
    }

    /// The screen rectangle of the map, as drawn last frame.
    pub fn map_rect(&self) -> egui::Rect {
        self.map.rect
    }

    /// Where a geographic point is on screen (as drawn last frame).
    pub fn screen_pos(&self, at: LatLon) -> Option<egui::Pos2> {
        self.map.screen_pos(at)
    }

    /// Where a point of the world frame (metres) is on screen.
    pub fn screen_pos_of_local(&self, x_m: f64, y_m: f64) -> Option<egui::Pos2> {
        let origin = self.surroundings.origin(&self.editor.plan);
        self.screen_pos(LatLon::from_local(
            armor_model::world::Point::new(x_m, y_m),
            origin,
        ))
    }

    pub fn set_tool(&mut self, tool: Tool) {
        self.map.tool = tool;
        self.map.pending.clear();
    }

    // ----- Files -----

    /// Starts a new plan on the system file `system` (may be empty: set it later).
    pub fn new_plan(&mut self, system: Option<&Path>) -> Report {
        let mut plan = Plan {
            name: "plan".to_owned(),
            ..Plan::default()
        };
        let base = std::env::current_dir().unwrap_or_default();
        if let Some(system) = system {
            plan.system = armor_runtime::fs::relative_path(system, &base)
                .to_string_lossy()
                .into_owned();
        }
        self.saved = plan.clone();
        self.editor.replace(plan);
        self.path = None;
        self.refresh_surroundings(true);
        // It names the follower only: the avoider its commands pass through, and what it
        // reads, run with it on demand.
        Ok("new plan: click the map with the waypoint tool (W) to draw its route".to_owned())
    }

    pub fn open(&mut self, file: &Path) -> Report {
        let text = std::fs::read_to_string(file)
            .with_context(|| format!("cannot read {}", file.display()))?;
        let plan = Plan::parse(&text).map_err(|problems| located_error(file, &problems))?;
        self.saved = plan.clone();
        self.editor.replace(plan);
        self.path = Some(file.to_path_buf());
        self.refresh_surroundings(true);
        Ok(format!("opened {}", file.display()))
    }

    /// Saves to `file` (save as: the plan's relative paths are rewritten for the new folder),
    /// or to the plan's own file.
    pub fn save(&mut self, file: Option<&Path>) -> Report {
        let Some(file) = file.map(Path::to_path_buf).or_else(|| self.path.clone()) else {
            anyhow::bail!("the plan has no file yet: use Save as");
        };
        let folder = folder_of(&file);
        let mut plan = self.editor.plan.clone();
        if folder != self.surroundings.base && !plan.system.is_empty() {
            plan.system = armor_runtime::fs::relative_path(&self.surroundings.system_file, &folder)
                .to_string_lossy()
                .into_owned();
        }
        armor_runtime::fs::write_atomically(&file, plan.to_xml().as_bytes())
            .with_context(|| format!("cannot save {}", file.display()))?;
        if plan != self.editor.plan {
            self.commands.push(PlanCommand::Change {
                plan: Box::new(plan.clone()),
                field: "save as".to_owned(),
            });
        }
        self.saved = plan;
        self.path = Some(file.clone());
        self.refresh_surroundings(false);
        Ok(format!("saved {}", file.display()))
    }

    /// Replaces the plan's waypoints and legs with a GPX file's (the system stays).
    pub fn import_gpx(&mut self, file: &Path) -> Report {
        let text = std::fs::read_to_string(file)
            .with_context(|| format!("cannot read {}", file.display()))?;
        let name = file
            .file_stem()
            .map(|stem| stem.to_string_lossy().into_owned())
            .unwrap_or_else(|| "imported".to_owned());
        let imported = plan::gpx::import(&text, &name, &self.editor.plan.system)
            .map_err(|problems| located_error(file, &problems))?;
        let mut plan = self.editor.plan.clone();
        plan.waypoints = imported.waypoints;
        plan.legs = imported.legs;
        let count = plan.waypoints.len();
        self.commands.push(PlanCommand::Change {
            plan: Box::new(plan),
            field: "import".to_owned(),
        });
        self.map.fit_requested = true;
        Ok(format!(
            "imported {count} waypoints from {}",
            file.display()
        ))
    }

    /// The plan's base map, as it names it.
    pub fn basemap_href(&self) -> Option<String> {
        self.editor
            .plan
            .basemap
            .as_ref()
            .map(|basemap| basemap.href.clone())
    }

    /// Draws the plan on the base map at `path` (an MBTiles file or a tile folder), named in
    /// the plan relative to its file; `none` or an empty path goes back to the world's tiles.
    /// An edit of the plan like any other (undone by Undo, kept by Save).
    pub fn choose_basemap(&mut self, path: &Path) -> Report {
        let mut plan = self.editor.plan.clone();
        let typed = path.to_string_lossy();
        let message = if matches!(typed.trim(), "" | "none") {
            plan.basemap = None;
            "the map shows the world's own tiles".to_owned()
        } else {
            let map = armor_runtime::basemap::Basemap::open(path).map_err(anyhow::Error::msg)?;
            let href = match self.path.as_deref() {
                Some(file) => armor_runtime::fs::relative_path(path, &folder_of(file)),
                None => std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf()),
            };
            plan.basemap = Some(plan::Basemap {
                href: href.display().to_string(),
                pos: Default::default(),
            });
            format!("the plan is drawn on the base map `{}`", map.name)
        };
        self.commands.push(PlanCommand::Change {
            plan: Box::new(plan),
            field: "base map".to_owned(),
        });
        Ok(message)
    }

    /// The compiled net, or why there is none.
    fn net_for_export(&self) -> anyhow::Result<MissionNet> {
        if let Some(first) = self.checked.errors.first() {
            anyhow::bail!(
                "the plan has problems; the first: {}: {}",
                first.pos,
                first.message
            );
        }
        self.checked
            .net()
            .cloned()
            .context("nothing to export: the plan has no route yet")
    }

    /// Writes the compiled mission for headless runs (`armor run FILE`), its system path
    /// right from where it is written.
    pub fn export_mission(&mut self, file: &Path) -> Report {
        let mut net = self.net_for_export()?;
        net.system =
            armor_runtime::fs::relative_path(&self.surroundings.system_file, &folder_of(file))
                .to_string_lossy()
                .into_owned();
        armor_runtime::fs::write_atomically(file, net.to_xml().as_bytes())
            .with_context(|| format!("cannot write {}", file.display()))?;
        Ok(format!(
            "exported the mission to {} ({} places, {} transitions)",
            file.display(),
            net.places.len(),
            net.transitions.len()
        ))
    }

    pub fn export_pnml(&mut self, file: &Path) -> Report {
        let net = self.net_for_export()?;
        armor_runtime::fs::write_atomically(file, net::to_pnml(&net).as_bytes())
            .with_context(|| format!("cannot write {}", file.display()))?;
        Ok(format!("exported PNML to {}", file.display()))
    }

    /// The text of the recovery copy.
    pub fn recovery_text(&self) -> String {
        self.editor.plan.to_xml()
    }

    /// Takes back a recovery copy of a plan that was at `original`.
    pub fn restore(&mut self, original: Option<&Path>, text: &str) -> Report {
        let plan = Plan::parse(text)
            .map_err(|problems| located_error(Path::new("the recovery copy"), &problems))?;
        self.saved = original
            .and_then(|path| std::fs::read_to_string(path).ok())
            .and_then(|text| Plan::parse(&text).ok())
            .unwrap_or_default();
        self.editor.replace(plan);
        self.path = original.map(Path::to_path_buf);
        self.refresh_surroundings(true);
        Ok("restored the recovery copy of the plan".to_owned())
    }

    // ----- The frame -----

    /// Applies the queued commands; returns what the status line should say.
    pub fn apply_commands(&mut self) -> Option<(String, bool)> {
        let mut status = None;
        for command in std::mem::take(&mut self.commands) {
            let undoing = matches!(command, PlanCommand::Undo | PlanCommand::Redo);
            match self.editor.apply(command) {
                Outcome::Nothing => {}
                Outcome::Done(text) => status = Some((text, false)),
                Outcome::Refused(reason) => status = Some((format!("refused: {reason}"), true)),
            }
            if undoing {
                self.inspector.drafts.clear();
            }
        }
        self.refresh_surroundings(false);
        self.recheck(false);
        status
    }

    /// Reloads the system and world when the plan names others (or `force`).
    fn refresh_surroundings(&mut self, force: bool) {
        let base = self
            .path
            .as_deref()
            .map(folder_of)
            .unwrap_or_else(|| std::env::current_dir().unwrap_or_default());
        if force || self.surroundings.key != key_of(&self.editor.plan, &base) {
            self.surroundings = PlanSurroundings::load(&self.editor.plan, &base);
            let origin = self.surroundings.origin(&self.editor.plan);
            self.map.set_world(self.surroundings.world.clone(), origin);
            let basemap = self.surroundings.basemap.as_deref().and_then(|path| {
                armor_runtime::basemap::Basemap::open(path)
                    .map_err(|err| tracing::error!("{err}"))
                    .ok()
            });
            self.map.set_basemap(basemap);
            self.checked_revision = None;
        }
    }

    /// Compiles and verifies the plan again when it changed.
    pub fn recheck(&mut self, catalog_changed: bool) {
        if catalog_changed {
            self.checked_revision = None;
        }
        let revision = self.editor.revision();
        if self.checked_revision == Some(revision) {
            return;
        }
        self.checked_revision = Some(revision);
        self.checked = Checked::of(
            &self.editor.plan,
            &self.surroundings,
            &self.inspector.catalog,
        );
        self.net_layout = None;
        self.net_view.fit_pending = true;
    }

    /// The net elements that come from the selection (a leg, or a waypoint's legs).
    pub fn highlighted(&self) -> BTreeSet<String> {
        let Some(compiled) = &self.checked.compiled else {
            return BTreeSet::new();
        };
        let legs: Vec<usize> = match &self.editor.selection {
            Selection::Leg(index) => vec![*index],
            Selection::Waypoint(name) => self
                .editor
                .plan
                .legs
                .iter()
                .enumerate()
                .filter(|(_, leg)| &leg.to == name)
                .map(|(index, _)| index)
                .collect(),
            _ => Vec::new(),
        };
        compiled
            .trace
            .iter()
            .filter(|(_, origin)| matches!(origin, Origin::Leg(index) if legs.contains(index)))
            .map(|(name, _)| name.clone())
            .collect()
    }

    /// The net of a run with its live marking, the current leg's elements lit: the run's plan
    /// ([`Self::watch_plan`]), else the plan edited.
    pub fn marking_ui(&mut self, ui: &mut egui::Ui, marking: &armor_model::net::Marking) {
        self.net_drawn_watched = self.watched.is_some();
        let (checked, net_layout, plan) = match &mut self.watched {
            Some(Watched {
                checked,
                layout,
                plan,
                ..
            }) => (&*checked, layout, &*plan),
            None => (&self.checked, &mut self.net_layout, &self.editor.plan),
        };
        let Some(net) = checked.net() else {
            // What keeps the run's plan from compiling, as the Mission view's panel says it.
            no_net_ui(ui, checked, plan, "run-no-net");
            return;
        };
        let current: BTreeSet<usize> = checked
            .compiled
            .iter()
            .flat_map(|compiled| {
                marking
                    .keys()
                    .filter_map(|place| match compiled.trace.get(place) {
                        Some(Origin::Leg(index)) => Some(*index),
                        _ => None,
                    })
            })
            .collect();
        let highlighted: BTreeSet<String> = checked
            .compiled
            .iter()
            .flat_map(|compiled| &compiled.trace)
            .filter(|(_, origin)| matches!(origin, Origin::Leg(index) if current.contains(index)))
            .map(|(name, _)| name.clone())
            .collect();
        let alternatives = checked
            .compiled
            .as_ref()
            .map(|compiled| compiled.alternatives.clone())
            .unwrap_or_default();
        let style = net_view::NetStyle {
            highlighted: &highlighted,
            marking: Some(marking),
            scroll_to_highlight: self.net_scrolled_for_marking.as_ref() != Some(marking),
            alternatives: &alternatives,
        };
        self.net_scrolled_for_marking = Some(marking.clone());
        let layout =
            net_layout.get_or_insert_with(|| net_view::layout(net, &net_view::measure_ui(ui)));
        net_view::net_ui(ui, net, layout, &style, &mut self.net_view);
    }

    /// The net's panel at the bottom of `ui`: its default size (resizable), or most of the
    /// window's height when enlarged. `contents` draws the net in it.
    ///
    /// At first sight the panel is as tall as the net at a readable zoom needs (up to half the
    /// height it shares with the map), so that the net is seen whole rather than cut at the
    /// panel's bottom; then it keeps the size the user gives it.
    pub fn net_panel_ui(
        &mut self,
        ui: &mut egui::Ui,
        id: &str,
        default_size: f32,
        contents: impl FnOnce(&mut MissionView, &mut egui::Ui),
    ) {
        // Enlarged or back, the map changes size a lot: framed again, so that it shows its
        // world whole rather than a corner of it (and its labels at the edge of that corner).
        if std::mem::replace(&mut self.net_was_enlarged, self.net_view.enlarged)
            != self.net_view.enlarged
        {
            self.map.fit_requested = true;
        }
        let panel = if self.net_view.enlarged {
            // Another id, so that the size the user dragged the small panel to is kept.
            egui::Panel::bottom(format!("{id}-enlarged"))
                .resizable(false)
                .exact_size(ui.available_height() * 0.7)
        } else {
            // A panel keeps the size it was first shown at: until the net is laid out its
            // size is the default, under another id, so that the net's own size is the first
            // one the panel shown with it gets.
            let (id, size) = match self.net_height_at_first_sight(ui) {
                Some(height) => {
                    // The map shrinks as the panel takes the net's size: framed again.
                    if !std::mem::replace(&mut self.net_panel_sized, true) {
                        self.map.fit_requested = true;
                    }
                    (
                        format!("{id}-sized"),
                        height.min(ui.available_height() * 0.5).max(NET_PANEL_MIN),
                    )
                }
                None => (id.to_owned(), default_size),
            };
            egui::Panel::bottom(id)
                .resizable(true)
                .default_size(size)
                .min_size(NET_PANEL_MIN)
        };
        panel.show(ui, |ui| contents(self, ui));
    }

    /// The height the net panel needs to show the whole net at a readable zoom: the net drawn
    /// last (the run's in the Run view), laid out now if it is the plan's and not yet; `None`
    /// while there is no net.
    fn net_height_at_first_sight(&mut self, ui: &egui::Ui) -> Option<f32> {
        let layout = if self.net_drawn_watched {
            self.watched
                .as_ref()
                .and_then(|watched| watched.layout.as_ref())
        } else {
            if self.net_layout.is_none()
                && let Some(net) = self.checked.net()
            {
                self.net_layout = Some(net_view::layout(net, &net_view::measure_ui(ui)));
            }
            self.net_layout.as_ref()
        }?;
        Some(layout.size.y * net_view::READABLE_ZOOM + net_view::HEADER_HEIGHT)
    }

    /// The net's elements that only the actions' alternatives have (drawn dashed).
    fn alternatives(&self) -> BTreeSet<String> {
        self.checked
            .compiled
            .as_ref()
            .map(|compiled| compiled.alternatives.clone())
            .unwrap_or_default()
    }

    /// The net view's zoom, pan and last frame's names, for the tests.
    pub fn net_view(&self) -> &net_view::NetViewState {
        &self.net_view
    }

    /// The net as laid out at the last frame: the run's in the Run view when it draws the
    /// run's plan ([`Self::watch_plan`]), else the plan edited's.
    pub fn net_layout(&self) -> Option<&net_view::Layout> {
        match &self.watched {
            Some(watched) if self.net_drawn_watched => watched.layout.as_ref(),
            _ => self.net_layout.as_ref(),
        }
    }

    /// The net panel: verification in words, then the net.
    pub fn net_ui(&mut self, ui: &mut egui::Ui) {
        self.net_drawn_watched = false;
        let highlighted = self.highlighted();
        let Some(net) = self.checked.net() else {
            no_net_ui(ui, &self.checked, &self.editor.plan, "mission-no-net");
            return;
        };
        let scroll = self.net_scrolled_for.as_ref() != Some(&self.editor.selection);
        self.net_scrolled_for = Some(self.editor.selection.clone());
        let alternatives = self.alternatives();
        let style = net_view::NetStyle {
            highlighted: &highlighted,
            marking: None,
            scroll_to_highlight: scroll && !highlighted.is_empty(),
            alternatives: &alternatives,
        };
        let layout = self
            .net_layout
            .get_or_insert_with(|| net_view::layout(net, &net_view::measure_ui(ui)));
        if let Some(element) = net_view::net_ui(ui, net, layout, &style, &mut self.net_view) {
            let selection = match self
                .checked
                .compiled
                .as_ref()
                .and_then(|c| c.trace.get(&element))
            {
                Some(Origin::Leg(index)) => Selection::Leg(*index),
                Some(Origin::Waypoint(name)) => Selection::Waypoint(name.clone()),
                _ => Selection::None,
            };
            self.commands.push(PlanCommand::Select(selection));
        }
    }
}

/// Why `plan` has no net ([`Checked::no_net_reasons`]), in the net's panel.
fn no_net_ui(ui: &mut egui::Ui, checked: &Checked, plan: &Plan, id: &str) {
    let (heading, reasons) = checked.no_net_reasons(plan);
    ui.label(heading);
    egui::ScrollArea::vertical().id_salt(id).show(ui, |ui| {
        for reason in reasons {
            ui.colored_label(ui.visuals().error_fg_color, reason);
        }
    });
}

/// The folder a file is in (`.` for a bare name).
fn folder_of(file: &Path) -> PathBuf {
    let folder = file
        .parent()
        .filter(|dir| !dir.as_os_str().is_empty())
        .unwrap_or_else(|| Path::new("."));
    std::path::absolute(folder).unwrap_or_else(|_| folder.to_path_buf())
}

/// Problems of a file as one error, a `FILE:LINE:COL: message` line each.
fn located_error(file: &Path, problems: &[Located]) -> anyhow::Error {
    let lines: Vec<String> = problems
        .iter()
        .map(|problem| format!("{}:{}: {}", file.display(), problem.pos, problem.message))
        .collect();
    anyhow::anyhow!("{}", lines.join("\n"))
}
