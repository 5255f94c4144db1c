//! The editing session over a [`Plan`]: the selection, the undo history and the commands the
//! map and the inspector queue during a frame. No egui here: the rules of editing a route
//! (where a clicked waypoint joins, what deleting one does to its legs) are tested without a
//! window.
//!
//! The route is the plan's legs in order, each starting where the previous one ended. A click
//! on the map appends a waypoint and a leg to it from the route's end; inserting splits a leg
//! at its middle; deleting a waypoint joins the legs on either side of it.

use armor_model::plan::{
    AreaKind, Graphic, GraphicKind, LatLon, Leg, Plan, Response, Unit, Waypoint,
};

use crate::common::history::History;
pub use crate::common::history::Outcome;

/// What is selected, on the map or in the net.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum Selection {
    #[default]
    None,
    Waypoint(String),
    /// A leg, by index in the route.
    Leg(usize),
    /// A tactical graphic, by index.
    Graphic(usize),
    /// A unit symbol, by index.
    Unit(usize),
}

/// Something on the map that can be dragged.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum Handle {
    Waypoint(String),
    Unit(usize),
    /// A corner of a graphic: the graphic's index, the corner's.
    Vertex(usize, usize),
}

/// An edit, queued during a frame and applied after it.
#[derive(Clone, Debug)]
pub enum PlanCommand {
    /// A click on the map: a new waypoint at the end of the route.
    AddWaypoint(LatLon),
    /// A new waypoint in the middle of this leg.
    InsertWaypoint(usize),
    /// A handle follows the pointer during a drag (no history step: see [`PlanCommand::Moved`]).
    Drag(Handle, LatLon),
    /// A drag ended; `before` is the plan when it began.
    Moved {
        before: Box<Plan>,
    },
    AddGraphic(Graphic),
    AddUnit {
        sidc: String,
        at: LatLon,
    },
    /// The inspector changed the plan. Successive changes with the same `field` (typing in one
    /// text box) make one undo step.
    Change {
        plan: Box<Plan>,
        field: String,
    },
    DeleteSelection,
    Select(Selection),
    Undo,
    Redo,
}

#[derive(Debug, Default)]
pub struct PlanEditor {
    pub plan: Plan,
    pub selection: Selection,
    history: History<Plan>,
    /// The field of the last [`PlanCommand::Change`], while no other edit came after it.
    changing: Option<String>,
    /// Counts every change of the plan or the selection: views recompute what derives from them
    /// when it moves.
    revision: u64,
}

impl PlanEditor {
    pub fn new(plan: Plan) -> Self {
        Self {
            plan,
            ..Self::default()
        }
    }

    pub fn revision(&self) -> u64 {
        self.revision
    }

    pub fn can_undo(&self) -> bool {
        self.history.can_undo()
    }

    /// Replaces the whole plan (open, import, restore): a fresh history.
    pub fn replace(&mut self, plan: Plan) {
        self.plan = plan;
        self.history = History::default();
        self.selection = Selection::None;
        self.changing = None;
        self.revision += 1;
    }

    /// The route's last waypoint, where the next leg starts: the end of the last leg, else the
    /// only waypoint so far.
    pub fn route_end(&self) -> Option<&str> {
        self.plan
            .legs
            .last()
            .map(|leg| leg.to.as_str())
            .or_else(|| self.plan.waypoints.last().map(|w| w.name.as_str()))
    }

    pub fn apply(&mut self, command: PlanCommand) -> Outcome {
        let before = self.plan.clone();
        let field = match &command {
            PlanCommand::Change { field, .. } => Some(field.clone()),
            _ => None,
        };
        let outcome = match command {
            PlanCommand::AddWaypoint(at) => self.add_waypoint(at),
            PlanCommand::InsertWaypoint(leg) => self.insert_waypoint(leg),
            PlanCommand::Drag(handle, to) => {
                self.drag(&handle, to);
                self.revision += 1;
                return Outcome::Nothing;
            }
            PlanCommand::Moved { before } => {
                if *before != self.plan {
                    self.history.record(*before);
                    self.changing = None;
                }
                self.revision += 1;
                return Outcome::Nothing;
            }
            PlanCommand::AddGraphic(graphic) => {
                let what = describe_graphic(&graphic);
                self.plan.graphics.push(graphic);
                self.selection = Selection::Graphic(self.plan.graphics.len() - 1);
                Outcome::Done(format!("added {what}"))
            }
            PlanCommand::AddUnit { sidc, at } => {
                let name = unique_name(&self.plan, "unit");
                self.plan.units.push(Unit {
                    name: name.clone(),
                    sidc,
                    position: at,
                    ..Unit::default()
                });
                self.selection = Selection::Unit(self.plan.units.len() - 1);
                Outcome::Done(format!("added unit `{name}`"))
            }
            PlanCommand::Change { plan, .. } => {
                self.plan = *plan;
                Outcome::Nothing
            }
            PlanCommand::DeleteSelection => self.delete_selection(),
            PlanCommand::Select(selection) => {
                if selection != self.selection {
                    self.selection = selection;
                    self.revision += 1;
                }
                return Outcome::Nothing;
            }
            PlanCommand::Undo => return self.step_history(true),
            PlanCommand::Redo => return self.step_history(false),
        };
        if self.plan != before {
            // Typing in one field goes back in one step; anything else is a step of its own.
            let merge = field.is_some() && field == self.changing;
            if !merge {
                self.history.record(before);
            }
            self.changing = field;
            self.revision += 1;
        }
        self.keep_selection_valid();
        outcome
    }

    fn step_history(&mut self, undo: bool) -> Outcome {
        let stepped = match undo {
            true => self.history.undo(&mut self.plan),
            false => self.history.redo(&mut self.plan),
        };
        if !stepped {
            return Outcome::Nothing;
        }
        self.changing = None;
        self.revision += 1;
        self.keep_selection_valid();
        Outcome::Done(if undo { "undone" } else { "redone" }.to_owned())
    }

    fn keep_selection_valid(&mut self) {
        let valid = match &self.selection {
            Selection::None => true,
            Selection::Waypoint(name) => self.plan.waypoint(name).is_some(),
            Selection::Leg(index) => *index < self.plan.legs.len(),
            Selection::Graphic(index) => *index < self.plan.graphics.len(),
            Selection::Unit(index) => *index < self.plan.units.len(),
        };
        if !valid {
            self.selection = Selection::None;
        }
    }

    fn add_waypoint(&mut self, at: LatLon) -> Outcome {
        let from = self.route_end().map(str::to_owned);
        let name = unique_name(&self.plan, "wp");
        self.plan.waypoints.push(Waypoint {
            name: name.clone(),
            position: at,
            ..Waypoint::default()
        });
        let Some(from) = from else {
            self.selection = Selection::Waypoint(name.clone());
            return Outcome::Done(format!("added the start `{name}`"));
        };
        let leg = unique_name(&self.plan, "leg");
        self.plan.legs.push(Leg {
            name: leg.clone(),
            from,
            to: name.clone(),
            ..Leg::default()
        });
        self.selection = Selection::Waypoint(name.clone());
        Outcome::Done(format!("added `{name}` and leg `{leg}`"))
    }

    /// Splits leg `index` (A → B) at its middle N: a new leg A → N that keeps the departure
    /// appointment and what runs while driving, and the old leg, now N → B, with everything
    /// about the arrival at B.
    fn insert_waypoint(&mut self, index: usize) -> Outcome {
        let Some(leg) = self.plan.legs.get(index) else {
            return Outcome::Refused("no such leg".to_owned());
        };
        let (Some(a), Some(b)) = (self.plan.waypoint(&leg.from), self.plan.waypoint(&leg.to))
        else {
            return Outcome::Refused(format!("leg `{}` names a missing waypoint", leg.name));
        };
        let middle = LatLon::new(
            (a.position.lat_deg + b.position.lat_deg) / 2.0,
            (a.position.lon_deg + b.position.lon_deg) / 2.0,
        );
        let name = unique_name(&self.plan, "wp");
        let first = Leg {
            name: unique_name(&self.plan, "leg"),
            from: leg.from.clone(),
            to: name.clone(),
            during: leg.during.clone(),
            not_before_unix_secs: leg.not_before_unix_secs,
            ..Leg::default()
        };
        let leg = &mut self.plan.legs[index];
        leg.from = name.clone();
        leg.not_before_unix_secs = None;
        self.plan.waypoints.push(Waypoint {
            name: name.clone(),
            position: middle,
            ..Waypoint::default()
        });
        self.plan.legs.insert(index, first);
        self.selection = Selection::Waypoint(name.clone());
        Outcome::Done(format!("inserted `{name}`"))
    }

    fn drag(&mut self, handle: &Handle, to: LatLon) {
        match handle {
            Handle::Waypoint(name) => {
                if let Some(waypoint) = self.plan.waypoints.iter_mut().find(|w| &w.name == name) {
                    waypoint.position = to;
                }
            }
            Handle::Unit(index) => {
                if let Some(unit) = self.plan.units.get_mut(*index) {
                    unit.position = to;
                }
            }
            Handle::Vertex(graphic, corner) => {
                if let Some(point) = self
                    .plan
                    .graphics
                    .get_mut(*graphic)
                    .and_then(|graphic| graphic.points.get_mut(*corner))
                {
                    *point = to;
                }
            }
        }
    }

    fn delete_selection(&mut self) -> Outcome {
        match self.selection.clone() {
            Selection::None => Outcome::Nothing,
            Selection::Waypoint(name) => self.delete_waypoint(&name),
            Selection::Leg(index) => self.delete_leg(index),
            Selection::Graphic(index) => {
                let graphic = self.plan.graphics.remove(index);
                self.selection = Selection::None;
                Outcome::Done(format!("deleted {}", describe_graphic(&graphic)))
            }
            Selection::Unit(index) => {
                let unit = self.plan.units.remove(index);
                self.selection = Selection::None;
                Outcome::Done(format!("deleted unit `{}`", unit.name))
            }
        }
    }

    /// Removes a waypoint and joins the legs on either side of it: the leg into it goes, the
    /// leg out of it now starts where the removed one did.
    fn delete_waypoint(&mut self, name: &str) -> Outcome {
        if let Some(user) = self.return_users(name).first() {
            return Outcome::Refused(format!(
                "`{name}` is where a contingency returns to ({user}): change that first"
            ));
        }
        let into = self.plan.legs.iter().position(|leg| leg.to == name);
        let out_of = self.plan.legs.iter().position(|leg| leg.from == name);
        match (into, out_of) {
            (Some(into), Some(out_of)) => {
                let from = self.plan.legs[into].from.clone();
                self.plan.legs[out_of].from = from;
                self.plan.legs.remove(into);
            }
            (Some(only), None) | (None, Some(only)) => {
                self.plan.legs.remove(only);
            }
            (None, None) => {}
        }
        self.plan.waypoints.retain(|waypoint| waypoint.name != name);
        self.selection = Selection::None;
        Outcome::Done(format!("deleted `{name}`"))
    }

    /// Removes a leg and joins its neighbours; its destination goes too unless another leg or a
    /// contingency still needs it.
    fn delete_leg(&mut self, index: usize) -> Outcome {
        if index >= self.plan.legs.len() {
            return Outcome::Nothing;
        }
        let leg = self.plan.legs.remove(index);
        if let Some(next) = self.plan.legs.get_mut(index) {
            next.from.clone_from(&leg.from);
        }
        let used = self
            .plan
            .legs
            .iter()
            .any(|other| other.from == leg.to || other.to == leg.to)
            || !self.return_users(&leg.to).is_empty();
        if !used {
            self.plan
                .waypoints
                .retain(|waypoint| waypoint.name != leg.to);
        }
        self.selection = Selection::None;
        Outcome::Done(format!("deleted leg `{}`", leg.name))
    }

    /// The contingencies that return to `waypoint`, described.
    fn return_users(&self, waypoint: &str) -> Vec<String> {
        let plan_wide = self.plan.contingencies.iter().map(|c| ("the plan", c));
        let per_leg = self.plan.legs.iter().flat_map(|leg| {
            leg.contingencies
                .iter()
                .map(move |c| (leg.name.as_str(), c))
        });
        plan_wide
            .chain(per_leg)
            .filter(
                |(_, c)| matches!(&c.response, Response::Return { waypoint: w } if w == waypoint),
            )
            .map(|(owner, c)| format!("{} of {owner}", c.trigger.describe()))
            .collect()
    }
}

/// `PREFIX1`, `PREFIX2`, …: the first not yet used by a waypoint, leg, graphic or unit (names
/// of net elements come from them, so they are kept apart).
pub fn unique_name(plan: &Plan, prefix: &str) -> String {
    let taken = |name: &str| {
        plan.waypoints.iter().any(|w| w.name == name)
            || plan.legs.iter().any(|l| l.name == name)
            || plan.graphics.iter().any(|g| g.name == name)
            || plan.units.iter().any(|u| u.name == name)
    };
    (1..)
        .map(|n| format!("{prefix}{n}"))
        .find(|name| !taken(name))
        .unwrap_or_else(|| prefix.to_owned())
}

pub fn describe_graphic(graphic: &Graphic) -> String {
    let kind = match graphic.kind {
        GraphicKind::PhaseLine => "phase line".to_owned(),
        GraphicKind::Boundary => "boundary".to_owned(),
        GraphicKind::Area(AreaKind::Named) => "area".to_owned(),
        GraphicKind::Area(kind) => format!("{} area", kind.as_str()),
    };
    format!("{kind} `{}`", graphic.name)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use armor_model::plan::{Contingency, Trigger};

    fn at(n: f64) -> LatLon {
        LatLon::new(43.0 + n * 1e-5, 1.0)
    }

    /// The route as `from>to` pairs.
    fn route(editor: &PlanEditor) -> Vec<String> {
        editor
            .plan
            .legs
            .iter()
            .map(|leg| format!("{}>{}", leg.from, leg.to))
            .collect()
    }

    fn three_clicks() -> PlanEditor {
        let mut editor = PlanEditor::default();
        for n in 0..3 {
            editor.apply(PlanCommand::AddWaypoint(at(f64::from(n))));
        }
        editor
    }

    #[test]
    fn clicks_append_waypoints_joined_by_legs_and_each_is_one_undo_step() {
        let mut editor = three_clicks();
        assert_eq!(route(&editor), ["wp1>wp2", "wp2>wp3"]);
        assert_eq!(editor.plan.legs[1].name, "leg2");
        assert_eq!(editor.selection, Selection::Waypoint("wp3".into()));
        editor.apply(PlanCommand::Undo);
        assert_eq!(route(&editor), ["wp1>wp2"]);
        assert_eq!(editor.selection, Selection::None);
        editor.apply(PlanCommand::Redo);
        assert_eq!(route(&editor), ["wp1>wp2", "wp2>wp3"]);
        while editor.can_undo() {
            editor.apply(PlanCommand::Undo);
        }
        assert_eq!(editor.plan, Plan::default());
    }

    #[test]
    fn insert_splits_a_leg_and_the_arrival_stays_with_the_destination() {
        let mut editor = three_clicks();
        let mut plan = editor.plan.clone();
        plan.legs[1].wait_secs = Some(30.0);
        plan.legs[1].not_before_unix_secs = Some(100.0);
        editor.apply(PlanCommand::Change {
            plan: Box::new(plan),
            field: "wait".into(),
        });
        editor.apply(PlanCommand::InsertWaypoint(1));
        assert_eq!(route(&editor), ["wp1>wp2", "wp2>wp4", "wp4>wp3"]);
        let (first, second) = (&editor.plan.legs[1], &editor.plan.legs[2]);
        assert_eq!(
            (first.not_before_unix_secs, first.wait_secs),
            (Some(100.0), None)
        );
        assert_eq!(
            (second.not_before_unix_secs, second.wait_secs),
            (None, Some(30.0))
        );
        let middle = editor.plan.waypoint("wp4").unwrap().position;
        assert!((middle.lat_deg - at(1.5).lat_deg).abs() < 1e-12);
        assert_eq!(
            editor.apply(PlanCommand::InsertWaypoint(9)),
            Outcome::Refused("no such leg".into())
        );
    }

    #[test]
    fn deleting_joins_the_route_and_refuses_a_return_target() {
        let mut editor = three_clicks();
        editor.apply(PlanCommand::AddWaypoint(at(3.0)));
        editor.apply(PlanCommand::Select(Selection::Waypoint("wp2".into())));
        editor.apply(PlanCommand::DeleteSelection);
        assert_eq!(route(&editor), ["wp1>wp3", "wp3>wp4"]);
        // The start: the route now begins at the next waypoint.
        editor.apply(PlanCommand::Select(Selection::Waypoint("wp1".into())));
        editor.apply(PlanCommand::DeleteSelection);
        assert_eq!(route(&editor), ["wp3>wp4"]);
        // A leg: its destination goes with it when nothing else needs it.
        editor.apply(PlanCommand::Select(Selection::Leg(0)));
        editor.apply(PlanCommand::DeleteSelection);
        assert!(route(&editor).is_empty());
        let names: Vec<&str> = editor
            .plan
            .waypoints
            .iter()
            .map(|w| w.name.as_str())
            .collect();
        assert_eq!(names, ["wp3"]);

        let mut editor = three_clicks();
        editor.plan.contingencies.push(Contingency {
            trigger: Trigger::Blocked,
            response: Response::Return {
                waypoint: "wp1".into(),
            },
            pos: Default::default(),
        });
        editor.apply(PlanCommand::Select(Selection::Waypoint("wp1".into())));
        let Outcome::Refused(reason) = editor.apply(PlanCommand::DeleteSelection) else {
            panic!("deleting a return target must be refused");
        };
        assert!(reason.contains("blocked of the plan"), "{reason}");
        assert_eq!(editor.plan.waypoints.len(), 3);
    }

    #[test]
    fn a_drag_is_one_undo_step_and_typing_in_one_field_is_one_too() {
        let mut editor = three_clicks();
        let before = Box::new(editor.plan.clone());
        for n in 0..5 {
            editor.apply(PlanCommand::Drag(
                Handle::Waypoint("wp2".into()),
                at(10.0 + f64::from(n)),
            ));
        }
        editor.apply(PlanCommand::Moved { before });
        assert_eq!(editor.plan.waypoint("wp2").unwrap().position, at(14.0));
        editor.apply(PlanCommand::Undo);
        assert_eq!(editor.plan.waypoint("wp2").unwrap().position, at(1.0));

        for text in ["g", "ga", "gat", "gate"] {
            let mut plan = editor.plan.clone();
            plan.legs[0].name = text.into();
            editor.apply(PlanCommand::Change {
                plan: Box::new(plan),
                field: "leg name".into(),
            });
        }
        editor.apply(PlanCommand::Undo);
        assert_eq!(editor.plan.legs[0].name, "leg1");
    }

    #[test]
    fn names_are_unique_across_kinds() {
        let mut editor = three_clicks();
        editor.apply(PlanCommand::AddUnit {
            sidc: "SFGPUCR----D---".into(),
            at: at(0.0),
        });
        editor.plan.legs[0].name = "wp4".into();
        assert_eq!(unique_name(&editor.plan, "wp"), "wp5");
        assert_eq!(unique_name(&editor.plan, "unit"), "unit2");
    }
}
