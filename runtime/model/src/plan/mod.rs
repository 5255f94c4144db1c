//! Mission plans: what an operator draws on a map — waypoints, legs between them, actions, time
//! constraints, contingencies and tactical graphics — and their compilation into a mission net.
//!
//! ```xml
//! <plan name="recon" system="system.xml" world="yard.world" start="2026-11-23T08:00:00Z">
//!   <navigation module="follower" speed_mps="0.5" clearance_m="0.1">
//!     <module name="avoider"/>
//!   </navigation>
//!   <waypoint name="home" lat="43.561536" lon="1.469049"/>
//!   <waypoint name="gate" lat="43.561590" lon="1.469250" symbol="SFGPUCR----"/>
//!   <leg from="home" to="gate" arrive_by="2026-11-23T08:05:00Z" wait_secs="10">
//!     <during>
//!       <module name="map_recorder"/>
//!       <alternative name="odometry" on="mapper"><module name="odometry_recorder"/></alternative>
//!     </during>
//!     <arrival until="observer.observation_done" for_secs="60">
//!       <module name="observer"><param name="sector_deg" value="360"/></module>
//!     </arrival>
//!   </leg>
//!   <leg from="gate" to="home" not_before="2026-11-23T08:10:00Z"/>
//!   <contingency on="blocked" do="hold"/>
//!   <area name="minefield" kind="no-go" margin_m="1">
//!     <point lat="43.56156" lon="1.46912"/> …
//!   </area>
//! </plan>
//! ```
//!
//! The legs are driven in the order written, each from where the previous one ended. The
//! navigation module (with its companions) runs on every leg with its goal set to the leg's
//! destination in the world frame; an action `during` a leg runs beside it, an action on
//! `arrival` runs at the destination until its event (or for at most `for_secs`). Time
//! constraints: `not_before` (do not leave before: an appointment), `arrive_by` (a deadline),
//! `wait_secs` (stay at the destination). Contingencies say what to do when the robot is
//! `blocked`, a module `failed`, the robot is `late`, or the localiser is `lost`: `skip` the rest of the leg, `hold` for
//! the operator (who may retry or skip), `return` to a waypoint and end there, or (`late` only)
//! `continue`. A leg's action may list `<alternative>`s: other sets of modules, tried in order
//! when a module the way in force depends on fails for good (its `on` modules, or those it does
//! without); once they are spent, the contingencies apply (`docs/plans.md`). An action
//! `throughout` runs from start to end (a recorder). The schema is
//! `assets/schema/plan.xsd`; [`compile`] makes the net, [`gpx`] exchanges waypoints and
//! routes with GIS tools, [`qgc`] plans with ground stations (QGroundControl's plan files) and
//! [`kml`] writes the plan for Google Earth and ATAK (what each carries: `docs/interchange.md`).
//!
//! Every leg is planned on the world ([`crate::planner`]): the robot, a disc of
//! `robot_radius_m` (the system's simulator's or avoider's `robot_radius_m` unless the plan
//! says), keeps `clearance_m` from obstacles and each no-go area's `margin_m` from it. A leg
//! with no way through is an error that says where the way is cut; the navigation module gets
//! the path in its `path` parameter, and the time constraints are checked along it.

use armor_module_api::xml::{Located, Pos};

mod compile;
pub mod gpx;
pub mod kml;
pub mod memory;
pub mod migrate;
pub mod objectives;
pub mod qgc;
pub mod repair;
mod xml;

pub use crate::geo::LatLon;
pub use compile::{
    CLEARANCE_M, Compiled, LegPaths, Origin, Switch, compile, compile_for, compile_with, plan_legs,
    plan_legs_with, plan_origin, plan_pairs, robot, robot_explained,
};
pub use xml::DEFAULT_LOCALISER;

/// A whole plan.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Plan {
    pub name: String,
    /// The system file, relative to the plan file.
    pub system: String,
    /// The world file the plan is drawn on; empty: the one the system's simulator loads.
    pub world: String,
    /// The geographic point of the world frame's (0, 0) when there is no world (a real robot);
    /// with a world, the world's origin is used and this one must agree.
    pub origin: Option<LatLon>,
    /// The offline map drawn under the plan (`<basemap href>`): an MBTiles file or a folder of
    /// `{z}/{x}/{y}.png` tiles, relative to the plan file; `None`: the world's own tiles.
    pub basemap: Option<Basemap>,
    /// The planned start, for the checks of time constraints (Unix seconds).
    pub start_unix_secs: Option<f64>,
    pub navigation: Navigation,
    /// Runs from the start of the mission to its end, in every place (a recorder).
    pub throughout: Option<Action>,
    pub waypoints: Vec<Waypoint>,
    pub legs: Vec<Leg>,
    /// What the operator wants done, for `armor plan` to turn into legs (`<objectives>`).
    pub objectives: Option<objectives::Objectives>,
    /// Contingencies for every leg that does not say otherwise.
    pub contingencies: Vec<Contingency>,
    pub graphics: Vec<Graphic>,
    pub units: Vec<Unit>,
    pub pos: Pos,
}

/// A plan's base map: where it is, and where the plan names it.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Basemap {
    pub href: String,
    pub pos: Pos,
}

/// How legs are driven: the module that drives to a goal, its parameters and events, the
/// modules that run with it.
#[derive(Clone, Debug, PartialEq)]
pub struct Navigation {
    pub module: String,
    /// Modules that run on every leg beside [`Navigation::module`] (an obstacle avoider).
    pub companions: Vec<String>,
    pub goal_x_param: String,
    pub goal_y_param: String,
    /// The parameter that gets the no-go areas (polygons in the world frame), if there are any.
    pub no_go_param: String,
    /// The parameter that gets the no-go areas' margins (metres, `;` between areas, in the
    /// order of `no_go_param`'s polygons), when one of them is not the default; empty: the
    /// margins are not passed on (a navigation module that has no such parameter).
    pub no_go_margins_param: String,
    /// The parameters that get the robot's radius and clearance (what the paths were planned
    /// for), when they are not the planner's defaults, so that the navigation module's replans
    /// are for the same robot; empty: not passed on.
    pub robot_radius_param: String,
    pub clearance_param: String,
    pub reached_event: String,
    pub blocked_event: String,
    /// The parameter that gets each leg's planned path (`X,Y X,Y …` in the world frame); empty:
    /// the path is not passed on (a navigation module that has no such parameter).
    pub path_param: String,
    /// The speed assumed for the earliest arrival times the time constraints are checked against.
    pub speed_mps: f64,
    /// The robot's radius for the paths planned; `None`: the system's (see [`robot`]).
    pub robot_radius_m: Option<f64>,
    /// How far the robot's body keeps from obstacles; `None`: the planner's default.
    pub clearance_m: Option<f64>,
    pub pos: Pos,
}

impl Default for Navigation {
    fn default() -> Self {
        Self {
            module: "follower".into(),
            companions: Vec::new(),
            goal_x_param: "goal_x_m".into(),
            goal_y_param: "goal_y_m".into(),
            no_go_param: "no_go".into(),
            no_go_margins_param: "no_go_margins_m".into(),
            robot_radius_param: "robot_radius_m".into(),
            clearance_param: "clearance_m".into(),
            reached_event: "goal_reached".into(),
            blocked_event: "blocked".into(),
            path_param: "path".into(),
            speed_mps: 0.5,
            robot_radius_m: None,
            clearance_m: None,
            pos: Pos::default(),
        }
    }
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct Waypoint {
    pub name: String,
    pub position: LatLon,
    /// A symbol to draw it with: an APP-6 / MIL-STD-2525 SIDC.
    pub symbol: Option<String>,
    pub pos: Pos,
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct Leg {
    /// The name its places and transitions start with (`leg1`, `leg2`, … when not given).
    pub name: String,
    pub from: String,
    pub to: String,
    /// Runs while the robot drives the leg.
    pub during: Option<Action>,
    /// Runs on arrival, before the wait.
    pub arrival: Option<Action>,
    /// Seconds to stay at the destination after the arrival action.
    pub wait_secs: Option<f64>,
    /// Do not leave before this date (an appointment), Unix seconds.
    pub not_before_unix_secs: Option<f64>,
    /// Arrive by this date (a deadline), Unix seconds.
    pub arrive_by_unix_secs: Option<f64>,
    /// Contingencies of this leg; they replace the plan's for the same trigger.
    pub contingencies: Vec<Contingency>,
    pub pos: Pos,
}

/// A set of modules with parameter values. On arrival it ends with `until` (an event
/// `MODULE.EVENT`), after `for_secs`, or whichever comes first.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Action {
    pub modules: Vec<ActionModule>,
    pub until: Option<String>,
    pub for_secs: Option<f64>,
    /// Other ways of doing the same (a leg's `<during>` or `<arrival>` only), in the order they
    /// are tried when a module that the way in force depends on fails for good.
    pub alternatives: Vec<Alternative>,
    pub pos: Pos,
}

/// Another set of modules for an action (`<alternative>`): what runs instead of the action's
/// own modules, or of the alternative before it, once one of the modules it answers has failed
/// for good (the runtime's `module.ID.failed`: its supervisor gave up on it).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Alternative {
    /// The name its places take after the action's (`leg1_drive_odometry`); `alt1`, `alt2`, …
    /// (its rank among the action's alternatives) when the plan gives none.
    pub name: String,
    /// The modules whose failure it answers, as written (`on="mapper sim"`); empty: those the
    /// way before it names and it does not ([`Alternative::answers`]).
    pub on: Vec<String>,
    /// What runs instead; none: the leg is driven, or the arrival waited, without them.
    pub modules: Vec<ActionModule>,
    pub pos: Pos,
}

impl Alternative {
    /// The name an alternative at `index` (from 0) takes when the plan gives none.
    pub fn default_name(index: usize) -> String {
        format!("alt{}", index + 1)
    }

    /// The modules whose failure it answers: its `on`, else the modules of `before` (the way
    /// tried before it) that it does without, in the order `before` names them.
    pub fn answers(&self, before: &[ActionModule]) -> Vec<String> {
        if !self.on.is_empty() {
            return self.on.clone();
        }
        before
            .iter()
            .filter(|module| !self.modules.iter().any(|own| own.name == module.name))
            .map(|module| module.name.clone())
            .collect()
    }
}

impl Action {
    /// Each way of doing the action in the order tried: its own modules, then each
    /// alternative's, with the modules whose failure leads to it (none for the first).
    pub fn strategies(&self) -> Vec<Strategy<'_>> {
        let mut ways = vec![Strategy {
            name: None,
            modules: &self.modules,
            answers: Vec::new(),
            pos: self.pos,
        }];
        for alternative in &self.alternatives {
            let before = ways.last().map_or(&[][..], |way| way.modules);
            ways.push(Strategy {
                name: Some(&alternative.name),
                modules: &alternative.modules,
                answers: alternative.answers(before),
                pos: alternative.pos,
            });
        }
        ways
    }
}

/// The names an alternative cannot take: its places and transitions, named after the action's
/// with `_NAME`, would take those of the leg's late drive and of the arrival's end.
const RESERVED_WAY_NAMES: [&str; 3] = ["late", "done", "timeout"];

impl Action {
    /// What is wrong with the action's alternatives (`tag`: the element that holds them, for
    /// the messages): a name given twice or taken by the leg's own places, an alternative that
    /// answers no failure.
    pub fn alternative_problems(&self, tag: &str) -> Vec<Located> {
        let mut problems = Vec::new();
        let mut names: std::collections::BTreeMap<&str, Pos> = std::collections::BTreeMap::new();
        let mut before = &self.modules;
        for alternative in &self.alternatives {
            let name = alternative.name.as_str();
            if RESERVED_WAY_NAMES.contains(&name) || name.ends_with("_failed") {
                problems.push(Located::new(
                    alternative.pos,
                    format!(
                        "alternative `{name}`: its places would take the names of the leg's own \
                         (`late`, `done`, `timeout` and names ending in `_failed` are taken); \
                         choose another name"
                    ),
                ));
            }
            if let Some(first) = names.get(name) {
                problems.push(Located::new(
                    alternative.pos,
                    format!(
                        "<{tag}> already has an alternative named `{name}` (line {})",
                        first.line
                    ),
                ));
            } else {
                names.insert(name, alternative.pos);
            }
            if alternative.answers(before).is_empty() {
                problems.push(Located::new(
                    alternative.pos,
                    format!(
                        "alternative `{name}` answers no failure: it runs every module the way \
                         before it runs; say which failures lead to it with on=\"MODULE\" (a \
                         provider such as the mapper), or leave out the module it does without"
                    ),
                ));
            }
            before = &alternative.modules;
        }
        problems
    }
}

/// One way of doing an action: [`Action::strategies`].
#[derive(Clone, Debug, PartialEq)]
pub struct Strategy<'a> {
    /// `None` for the action's own modules, else the alternative's name.
    pub name: Option<&'a str>,
    pub modules: &'a [ActionModule],
    /// The modules whose failure, in a way tried before, leads here.
    pub answers: Vec<String>,
    /// Where the plan writes it (the action, or the alternative).
    pub pos: Pos,
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct ActionModule {
    pub name: String,
    pub params: Vec<ActionParam>,
    pub pos: Pos,
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct ActionParam {
    pub name: String,
    pub value: String,
    pub pos: Pos,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Contingency {
    pub trigger: Trigger,
    pub response: Response,
    pub pos: Pos,
}

#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Trigger {
    /// The navigation reports that the robot makes no progress.
    Blocked,
    /// The module failed for good (the runtime's `module.ID.failed`).
    Failed { module: String },
    /// The leg's deadline passed before the arrival.
    Late,
    /// The localiser `module` reports that it does not know where the robot is (its `lost`
    /// event; the module is `localiser` unless the contingency names another).
    Lost { module: String },
    /// The battery runs low: the module that models or measures it (`sim` unless named) reports
    /// `low_battery`. Its response is to return to where the plan starts unless it says.
    LowBattery { module: String },
    /// The robot has not heard its operator for `after_secs` (run time): the team bridge
    /// (`armor-team robot`) tells the run when the radio link is lost and found again, and the
    /// run reports `link.lost.AFTER_SECS` once per outage (`docs/team.md`). Without such a
    /// contingency the mission goes on.
    LinkLost { after_secs: u32 },
}

impl Trigger {
    pub fn describe(&self) -> String {
        match self {
            Trigger::Blocked => "blocked".into(),
            Trigger::Failed { module } => format!("failed (module `{module}`)"),
            Trigger::Late => "late".into(),
            Trigger::Lost { module } => format!("lost (module `{module}`)"),
            Trigger::LowBattery { module } => format!("low_battery (module `{module}`)"),
            Trigger::LinkLost { after_secs } => format!("link_lost (after {after_secs} s)"),
        }
    }
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Response {
    /// Give up the rest of the leg (its arrival action and wait) and go on with the next one.
    Skip,
    /// Stop and wait for the operator, who fires `LEG_retry` or `LEG_skip`.
    Hold,
    /// Drive to the waypoint and end the mission there.
    Return { waypoint: String },
    /// Go on as if nothing happened (only for `late`: the net records that the robot was late).
    Continue,
    /// Only for `blocked` and `late`: hold as [`Response::Hold`] does (the net is the same),
    /// and the run applies the best option of the repair it computes ([`repair`]: a way round,
    /// skipping the leg, returning; for a late leg, its deadline pushed back or dropped), at
    /// once or `after_secs` (run time) after proposing it, the operator free to choose another
    /// meanwhile or to override.
    Repair { after_secs: Option<u32> },
}

/// A tactical graphic: a line or an area with a meaning, drawn on the map.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Graphic {
    pub kind: GraphicKind,
    pub name: String,
    pub points: Vec<LatLon>,
    /// For a phase line: when units are to cross it (shown on the map like a plan's
    /// synchronisation line).
    pub at_unix_secs: Option<f64>,
    /// For a no-go area: how far the robot's body keeps from it; `None`:
    /// [`crate::planner::DEFAULT_AREA_MARGIN_M`].
    pub margin_m: Option<f64>,
    pub pos: Pos,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GraphicKind {
    #[default]
    PhaseLine,
    Boundary,
    Area(AreaKind),
}

/// What an area means; only `no-go` changes how the robot drives.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AreaKind {
    #[default]
    NoGo,
    Objective,
    Assembly,
    Named,
}

impl AreaKind {
    pub const ALL: [AreaKind; 4] = [
        AreaKind::NoGo,
        AreaKind::Objective,
        AreaKind::Assembly,
        AreaKind::Named,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            AreaKind::NoGo => "no-go",
            AreaKind::Objective => "objective",
            AreaKind::Assembly => "assembly",
            AreaKind::Named => "named",
        }
    }
}

/// A unit symbol on the map.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Unit {
    pub name: String,
    /// The symbol identification code (APP-6 / MIL-STD-2525).
    pub sidc: String,
    pub position: LatLon,
    pub pos: Pos,
}

impl Plan {
    pub fn waypoint(&self, name: &str) -> Option<&Waypoint> {
        self.waypoints.iter().find(|waypoint| waypoint.name == name)
    }

    /// Every contingency of the plan: the plan's own, then each leg's.
    pub fn contingencies_mut(&mut self) -> impl Iterator<Item = &mut Contingency> {
        self.contingencies.iter_mut().chain(
            self.legs
                .iter_mut()
                .flat_map(|leg| leg.contingencies.iter_mut()),
        )
    }

    /// The waypoints the route passes, in order: the first leg's start, then each leg's end
    /// (for a plan [`Plan::parse`] accepts, one more than its legs); none without legs. The
    /// names are looked up in a map: a plan of 10,000 legs takes no longer than its size.
    pub fn route(&self) -> Vec<&Waypoint> {
        let Some(first) = self.legs.first() else {
            return Vec::new();
        };
        let mut by_name: std::collections::HashMap<&str, &Waypoint> =
            std::collections::HashMap::with_capacity(self.waypoints.len());
        for waypoint in &self.waypoints {
            // The first of a name, as `waypoint` finds it.
            by_name.entry(waypoint.name.as_str()).or_insert(waypoint);
        }
        std::iter::once(&first.from)
            .chain(self.legs.iter().map(|leg| &leg.to))
            .filter_map(|name| by_name.get(name.as_str()).copied())
            .collect()
    }

    /// The no-go areas.
    pub fn no_go_areas(&self) -> impl Iterator<Item = &Graphic> {
        self.graphics
            .iter()
            .filter(|graphic| graphic.kind == GraphicKind::Area(AreaKind::NoGo))
    }

    /// The contingency that applies to `trigger` on leg `leg`: the leg's own, else the plan's.
    pub fn contingency<'a>(&'a self, leg: &'a Leg, trigger: &Trigger) -> Option<&'a Contingency> {
        leg.contingencies
            .iter()
            .chain(&self.contingencies)
            .find(|contingency| &contingency.trigger == trigger)
    }

    /// The contingency whose trigger matches: the leg's own, else the plan's.
    pub fn contingency_on<'a>(
        &'a self,
        leg: &'a Leg,
        matches: impl Fn(&Trigger) -> bool,
    ) -> Option<&'a Contingency> {
        leg.contingencies
            .iter()
            .chain(&self.contingencies)
            .find(|contingency| matches(&contingency.trigger))
    }

    /// The plan's contingencies, then each leg's.
    pub fn every_contingency(&self) -> impl Iterator<Item = &Contingency> {
        self.contingencies
            .iter()
            .chain(self.legs.iter().flat_map(|leg| &leg.contingencies))
    }

    /// Every module whose failure some contingency handles, sorted, once each.
    pub fn failure_modules(&self) -> Vec<String> {
        let mut modules: Vec<String> = self
            .every_contingency()
            .filter_map(|contingency| match &contingency.trigger {
                Trigger::Failed { module } => Some(module.clone()),
                _ => None,
            })
            .collect();
        modules.sort_unstable();
        modules.dedup();
        modules
    }
}

/// Checks the form of a symbol identification code: 15 characters of APP-6 B / MIL-STD-2525 C
/// (letters, digits, `-` and `*`, the second an affiliation) or 20 digits of APP-6 D /
/// MIL-STD-2525 D. The message says what is wrong.
pub fn check_sidc(code: &str) -> Result<(), String> {
    let chars: Vec<char> = code.chars().collect();
    match chars.len() {
        15 => {
            if let Some(bad) = chars
                .iter()
                .find(|c| !(c.is_ascii_alphanumeric() || **c == '-' || **c == '*'))
            {
                return Err(format!("`{bad}` is not allowed in a 15-character SIDC"));
            }
            let affiliation = chars[1].to_ascii_uppercase();
            if !"PUAFNSHGWMDLJK-*".contains(affiliation) {
                return Err(format!(
                    "`{}` (the second character) is not an affiliation (F friend, H hostile, N neutral, U unknown, …)",
                    chars[1]
                ));
            }
            Ok(())
        }
        20 => {
            if chars.iter().all(char::is_ascii_digit) {
                Ok(())
            } else {
                Err("a 20-character SIDC (APP-6 D) has only digits".into())
            }
        }
        n => Err(format!(
            "a SIDC has 15 characters (APP-6 B, MIL-STD-2525 C) or 20 digits (APP-6 D), not {n}"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sidc_forms() {
        assert_eq!(check_sidc("SFGPUCI----K---"), Ok(()));
        assert_eq!(check_sidc("10031000001211000000"), Ok(()));
        assert!(check_sidc("SFGP").expect_err("refused").contains("not 4"));
        assert!(
            check_sidc("SQGPUCI--------")
                .expect_err("refused")
                .contains("affiliation")
        );
        assert!(
            check_sidc("SFGPUCI----K-%-")
                .expect_err("refused")
                .contains("`%`")
        );
        assert!(check_sidc("1003100000121100000X").is_err());
    }
}
