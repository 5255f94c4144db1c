//! Plan updates of a running mission (issue 39), as the operator sees them: the plan the run
//! plays, kept apart from the plan edited in the Mission view, so that the Run view never draws
//! an edit the robot has not taken; "Send to robot" over the Mission view, which sends the plan
//! edited as an update (`armor ctl update`) and shows the run's answer until dismissed; and the
//! Run view's list of the updates the run reports, whoever sent them (the studio, `armor ctl`
//! from elsewhere, a module reporting an area), after each of which the run's plan is asked
//! for again and drawn.

use armor_model::plan::Plan;
use armor_protocol::{MissionStatus, RepairOption, UpdateRecord};
use egui::{Color32, RichText, Ui};

use super::session::UpdateAnswer;
use crate::common::draw::state_colour;

/// Updates listed in the Run view: the latest, oldest first.
const LISTED: usize = 8;

/// A plan as the run plays it.
#[derive(Clone, Debug)]
pub struct RunPlan {
    pub plan: Plan,
    /// Its text as the studio writes a plan ([`Plan::to_xml`]): two plans are the same plan
    /// when their texts are (two parses of one file differ by the positions they keep).
    pub xml: String,
}

impl RunPlan {
    pub fn of_plan(plan: Plan) -> RunPlan {
        RunPlan {
            xml: plan.to_xml(),
            plan,
        }
    }

    /// The plan in `text`, or why it does not read (the first problem, located in `source`).
    pub fn of_text(text: &str, source: &str) -> Result<RunPlan, NoRunPlan> {
        Plan::parse(text).map(RunPlan::of_plan).map_err(|problems| {
            NoRunPlan::Unreadable(match problems.first() {
                Some(problem) => format!("{source}:{}: {}", problem.pos, problem.message),
                None => format!("{source} does not read as a plan"),
            })
        })
    }
}

/// Why the studio has no plan of the run's.
#[derive(Clone, Debug, PartialEq)]
pub enum NoRunPlan {
    /// The run sent none: its words when it refused, or that it sent nothing.
    NotSent(String),
    /// The text does not read as a plan: its first problem, located.
    Unreadable(String),
}

impl std::fmt::Display for NoRunPlan {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NoRunPlan::NotSent(why) => write!(f, "the run sent no plan: {why}"),
            NoRunPlan::Unreadable(why) => f.write_str(why),
        }
    }
}

/// What the studio knows of the updates of the run it watches.
#[derive(Default)]
pub struct Updates {
    /// The plan the run plays: read from its file when the run started (or from the run's
    /// files, attached), then replaced by each update taken ([`Self::set_run_plan`]).
    run_plan: Option<RunPlan>,
    /// Counts the changes of `run_plan`.
    run_plan_changes: u64,
    /// The run's answer to the operator's last update, shown until dismissed.
    pub answer: Option<UpdateAnswer>,
    /// An update sent, its answer not come yet.
    pub sending: bool,
    /// The last update taken whose plan the run sent.
    pub plan_after_update: u32,
    /// Why the run's plan after an update taken could not be had: the map shows the one
    /// before it, and says so.
    pub plan_problem: Option<String>,
    /// An update taken while the operator had edits of their own (which are kept): its
    /// number, for the Mission view to say that sending them replaces it.
    pub changed_under_edits: Option<u32>,
    /// The revisions of the plan edited and of the run's last compared, and whether they
    /// differed.
    compared: Option<((u64, u64), bool)>,
}

impl Updates {
    /// A new run: nothing sent, nothing answered; `run_plan` is what it plays.
    pub fn restart(&mut self, run_plan: Option<RunPlan>) {
        *self = Updates {
            run_plan,
            ..Updates::default()
        };
    }

    /// The plan the run plays, as far as the studio knows.
    pub fn run_plan(&self) -> Option<&RunPlan> {
        self.run_plan.as_ref()
    }

    /// The run plays `plan` now.
    pub fn set_run_plan(&mut self, plan: RunPlan) {
        self.run_plan = Some(plan);
        self.run_plan_changes += 1;
    }

    /// Whether `edited` (the Mission view's plan, at `revision` of its editor) is not the plan
    /// the run plays; compared again only when either changed.
    pub fn differs(&mut self, edited: &Plan, revision: u64) -> bool {
        let Some(run_plan) = &self.run_plan else {
            return false;
        };
        let key = (revision, self.run_plan_changes);
        if let Some((seen, differs)) = self.compared
            && seen == key
        {
            return differs;
        }
        let differs = edited.to_xml() != run_plan.xml;
        self.compared = Some((key, differs));
        differs
    }
}

/// The run's answer to the operator's update, in its colour, with the button that dismisses
/// it; returns whether it was dismissed.
pub fn answer_ui(ui: &mut Ui, answer: &UpdateAnswer, id: &str) -> bool {
    let (colour, head) = if answer.taken {
        (taken_colour(), "✔ Taken by the robot")
    } else {
        (refused_colour(), "✖ Not taken")
    };
    let mut dismissed = false;
    egui::Frame::group(ui.style())
        .stroke(egui::Stroke::new(1.5, colour))
        .show(ui, |ui| {
            ui.horizontal(|ui| {
                ui.label(RichText::new(head).strong().color(colour));
                dismissed = ui
                    .push_id(id, |ui| ui.button("Dismiss"))
                    .inner
                    .on_hover_text("hide this answer (the Run view lists every update)")
                    .clicked();
            });
            ui.label(&answer.message);
            if !answer.taken {
                ui.label(
                    RichText::new(
                        "Your edits are kept in the Mission view; the run goes on with its plan.",
                    )
                    .small(),
                );
            }
        });
    dismissed
}

/// The Run view's list of the updates the run reports: number, run time, taken or refused,
/// what was sent, and the first line of what it did or why not (all of it on hover).
pub fn list_ui(ui: &mut Ui, mission: &MissionStatus) {
    let updates = &mission.updates;
    if updates.is_empty() {
        ui.label(
            RichText::new(
                "none yet: edit the plan in the Mission view, then Send to robot (or armor ctl \
                 update)",
            )
            .weak(),
        );
        return;
    }
    let skipped = updates.len().saturating_sub(LISTED);
    if skipped > 0 {
        ui.label(RichText::new(format!("{skipped} earlier not listed")).weak());
    }
    for update in &updates[skipped..] {
        record_ui(ui, update);
    }
}

fn record_ui(ui: &mut Ui, update: &UpdateRecord) {
    let (word, colour) = if update.taken {
        ("taken", taken_colour())
    } else {
        ("refused", refused_colour())
    };
    ui.horizontal_wrapped(|ui| {
        ui.label(RichText::new(format!("{}", update.number)).strong());
        ui.label(format!("at {:.1} s", update.run_secs));
        ui.label(RichText::new(word).strong().color(colour));
        ui.label(RichText::new(&update.file).weak());
    });
    let first = update.message.lines().next().unwrap_or_default();
    // What the run said: its first line as far as the panel is wide, the whole on hover.
    ui.add(egui::Label::new(RichText::new(first).small()).truncate())
        .on_hover_text(&update.message);
}

/// An option's costs in words: the distance and time left, the legs it gives up, the
/// deadlines it misses.
fn costs(option: &RepairOption) -> String {
    let mut parts = vec![format!("{:.0} m left to drive", option.distance_m)];
    parts.push(match option.duration_secs {
        Some(secs) if secs >= 60.0 => {
            let whole = secs.round() as u64;
            format!("{} min {} s", whole / 60, whole % 60)
        }
        Some(secs) => format!("{secs:.0} s"),
        None => "for as long as it takes".to_owned(),
    });
    if !option.legs_dropped.is_empty() {
        let legs: Vec<String> = option
            .legs_dropped
            .iter()
            .map(|leg| format!("`{leg}`"))
            .collect();
        parts.push(format!("gives up {}", legs.join(", ")));
    }
    parts.push(if option.deadlines_missed.is_empty() {
        "meets every deadline".to_owned()
    } else {
        format!("misses: {}", option.deadlines_missed.join("; "))
    });
    parts.join(" · ")
}

pub fn taken_colour() -> Color32 {
    state_colour(armor_protocol::ModuleState::Running)
}

pub fn refused_colour() -> Color32 {
    state_colour(armor_protocol::ModuleState::Failed)
}

impl super::RunView {
    /// Whether the Mission view's plan is the one the run plays (its file, or the copy of an
    /// attached run's) while the run goes on: the plan the operator may edit and send.
    pub fn watches(&self, mission: &crate::mission::MissionView) -> bool {
        self.is_running()
            && self.updates.run_plan().is_some()
            && mission.path().is_some()
            && self.session_target() == mission.path()
    }

    /// Takes the run's answers to the operator's updates and the plan it plays after an update
    /// taken; has the Mission view draw that plan in the Run view, and follow it when the
    /// operator has no edits of their own (edits are never overwritten: the Mission view says
    /// that sending them replaces the robot's new plan). Called every frame, whatever the view.
    pub fn sync_plan(&mut self, mission: Option<&mut crate::mission::MissionView>) {
        let Some(session) = &self.session else {
            return;
        };
        let target = session.options.target.clone();
        let (answers, refreshed) = {
            let mut shared = session.shared();
            (
                std::mem::take(&mut shared.update_answers),
                shared.running_plan.take(),
            )
        };
        let before = (!answers.is_empty() || refreshed.is_some())
            .then(|| self.updates.run_plan().map(|plan| plan.xml.clone()))
            .flatten();
        // The update that changed the run's plan this frame, by its number when known.
        let mut changed_by: Option<Option<u32>> = None;
        for answer in answers {
            self.updates.sending = false;
            if answer.taken
                && let Some(text) = &answer.text
            {
                match RunPlan::of_text(text, "the plan sent") {
                    Ok(plan) => {
                        self.updates.set_run_plan(plan);
                        changed_by = Some(None);
                    }
                    // The studio wrote it: a plan it cannot read back is its own defect.
                    Err(why) => tracing::error!("the plan sent does not read back: {why}"),
                }
            }
            let said = answer.message.lines().next().unwrap_or_default().to_owned();
            self.messages.push((answer.taken, said));
            self.updates.answer = Some(answer);
        }
        if let Some(refreshed) = refreshed
            && refreshed.after_update > self.updates.plan_after_update
        {
            let number = refreshed.after_update;
            self.updates.plan_after_update = number;
            match refreshed
                .text
                .and_then(|text| RunPlan::of_text(&text, "the run's plan"))
            {
                Ok(plan) => {
                    self.updates.plan_problem = None;
                    if self
                        .updates
                        .run_plan()
                        .is_none_or(|known| known.xml != plan.xml)
                    {
                        self.updates.set_run_plan(plan);
                        changed_by = Some(Some(number));
                    }
                }
                Err(why) => {
                    self.updates.plan_problem = Some(format!(
                        "the map shows the plan before update {number}: the run's plan after it \
                         did not come ({why})"
                    ));
                }
            }
        }
        let Some(mission) = mission else {
            return;
        };
        if mission.path() != Some(target.as_path()) {
            mission.watch_plan(None);
            return;
        }
        if let (Some(by), Some(run_plan)) = (changed_by, self.updates.run_plan()) {
            let edited = mission.plan().to_xml();
            if before.as_ref() == Some(&edited) {
                // No edits of the operator's: the Mission view shows what the robot does.
                mission.take_plan(run_plan.plan.clone(), "the robot's plan");
                self.updates.changed_under_edits = None;
                if let Some(number) = by {
                    self.messages.push((
                        true,
                        format!("the Mission view follows the robot's plan (update {number})"),
                    ));
                }
            } else if edited != run_plan.xml {
                self.updates.changed_under_edits = by;
            } else {
                self.updates.changed_under_edits = None;
            }
        }
        mission.watch_plan(
            self.updates
                .run_plan()
                .map(|plan| (&plan.plan, plan.xml.as_str())),
        );
    }

    /// Sends the Mission view's plan to the run as an update of the plan it plays.
    pub fn send_plan(&mut self, mission: &crate::mission::MissionView) {
        let Some(session) = self.session.as_ref().filter(|session| session.is_running()) else {
            self.messages
                .push((false, "no run to send the plan to".to_owned()));
            return;
        };
        let name = mission
            .path()
            .and_then(std::path::Path::file_name)
            .map_or_else(
                || "the plan".to_owned(),
                |name| name.to_string_lossy().into_owned(),
            );
        session.send_update(
            format!("{name} (sent from the studio)"),
            mission.plan().to_xml(),
        );
        self.updates.sending = true;
        self.updates.answer = None;
    }

    /// Why "Send to robot" is greyed, or `None` when it may be pressed.
    fn why_not_send(&mut self, mission: &crate::mission::MissionView) -> Option<&'static str> {
        // With a key, the role is known once the control link proved it.
        let proven = self.session.as_ref().is_some_and(|session| {
            session.options.secret.is_none() || session.shared().role.is_some()
        });
        let differs = self
            .updates
            .differs(mission.plan(), mission.editor.revision());
        if !self.may_command() {
            Some("attached with an observer's key: sending a plan needs an operator's")
        } else if !proven {
            Some("the run has not said yet what the studio's key may do")
        } else if self.updates.sending {
            Some("waiting for the run's answer to the update sent")
        } else if !differs {
            Some("the robot runs this plan already: edit it, then send it")
        } else if !mission.checked().errors.is_empty() {
            Some("the plan has problems (the net panel lists them): the run would refuse it")
        } else {
            None
        }
    }

    /// The bar over the Mission view while the run plays its plan: whether the plan shown is
    /// the robot's, "Send to robot", "Take the robot's plan", and the run's answer.
    pub fn send_bar_ui(&mut self, ui: &mut Ui, mission: &mut crate::mission::MissionView) {
        let why_not = self.why_not_send(mission);
        let differs = self
            .updates
            .differs(mission.plan(), mission.editor.revision());
        ui.horizontal_wrapped(|ui| {
            ui.label(
                RichText::new(" Running on the robot ")
                    .strong()
                    .color(Color32::WHITE)
                    .background_color(taken_colour()),
            );
            let send = ui
                .add_enabled(why_not.is_none(), egui::Button::new("⬆ Send to robot"))
                .on_hover_text(
                    "send this plan to the run as an update (armor ctl update): the mission \
                     moves to it without a restart, or the run says why not",
                );
            let send = match why_not {
                Some(why) => send.on_disabled_hover_text(why),
                None => send,
            };
            if send.clicked() {
                self.send_plan(mission);
            }
            if ui
                .add_enabled(differs, egui::Button::new("↺ Take the robot's plan"))
                .on_hover_text("drop the edits not sent: the plan the robot runs (Ctrl+Z undoes)")
                .on_disabled_hover_text("the plan shown is the robot's")
                .clicked()
                && let Some(run_plan) = self.updates.run_plan()
            {
                mission.take_plan(run_plan.plan.clone(), "the robot's plan");
                self.updates.changed_under_edits = None;
            }
            if self.updates.sending {
                ui.spinner();
                ui.label("sending the update…");
            } else if differs {
                ui.label(
                    "Edited: the robot runs the plan without these edits until they are sent.",
                );
            } else {
                ui.label("The plan shown is the one the robot runs.");
            }
        });
        let repair = self
            .status()
            .and_then(|status| status.mission)
            .and_then(|mission| mission.repair);
        if let Some(repair) = repair {
            ui.label(
                RichText::new(format!(
                    "Leg `{}` cannot be completed: the Run view lists the repairs proposed, or \
                     send a plan.",
                    repair.leg
                ))
                .color(ui.visuals().warn_fg_color),
            );
        }
        if let (Some(number), true) = (self.updates.changed_under_edits, differs) {
            ui.label(
                RichText::new(format!(
                    "The robot's plan changed while you edited (update {number}, see the Run \
                     view): sending yours replaces it."
                ))
                .color(ui.visuals().warn_fg_color),
            );
        }
        if let Some(answer) = &self.updates.answer
            && answer_ui(ui, answer, "mission-update-answer")
        {
            self.updates.answer = None;
        }
    }

    /// The repair the mission proposes while a leg cannot be completed as planned: why, when
    /// the plan's default applies by itself (counting down to it at `run_secs`, the run's
    /// time), each option with its costs and the button that applies it (`armor ctl repair N`;
    /// greyed, with the reason, for an observer's key). Returns the option chosen.
    pub(super) fn repair_ui(
        &mut self,
        ui: &mut Ui,
        mission: &MissionStatus,
        run_secs: f64,
    ) -> Option<u32> {
        let repair = mission.repair.as_ref()?;
        let may_command = self.may_command();
        let running = self.is_running() && mission.outcome.is_none();
        let may = running && may_command && !self.updates.sending;
        let why_not = if !may_command {
            "attached with an observer's key: a repair needs an operator's"
        } else if !running {
            "the run is over"
        } else {
            "waiting for the run's answer to the update sent"
        };
        let warn = ui.visuals().warn_fg_color;
        let mut chosen = None;
        egui::Frame::group(ui.style())
            .stroke(egui::Stroke::new(1.5, warn))
            .show(ui, |ui| {
                ui.label(
                    RichText::new(format!("Leg `{}` cannot be completed", repair.leg))
                        .strong()
                        .color(warn),
                );
                ui.label(&repair.why);
                // A countdown is the operator's to act on: as large as the rest of the card.
                let default = RichText::new(default_text(
                    repair.default_option,
                    repair.default_at_run_secs,
                    run_secs,
                ));
                ui.label(if repair.default_at_run_secs.is_some() {
                    default.color(warn)
                } else {
                    default.small()
                });
                for option in &repair.options {
                    ui.horizontal_wrapped(|ui| {
                        let apply = ui
                            .add_enabled(may, egui::Button::new(format!("Apply {}", option.number)))
                            .on_hover_text(format!(
                                "armor ctl repair {}: the run takes it as a plan update",
                                option.number
                            ))
                            .on_disabled_hover_text(why_not);
                        if apply.clicked() {
                            chosen = Some(option.number);
                        }
                        ui.label(
                            RichText::new(format!("{}: {}", option.kind.as_str(), option.summary))
                                .strong(),
                        );
                    });
                    ui.label(RichText::new(costs(option)).small());
                }
            });
        chosen
    }

    /// The Run view's section on plan updates: the answer to the operator's last one, the
    /// run's list, and a word when the map could not follow.
    pub(super) fn updates_ui(&mut self, ui: &mut Ui, mission: &MissionStatus) {
        ui.label(RichText::new(format!("Plan updates ({})", mission.updates.len())).strong());
        if self.updates.sending {
            ui.horizontal(|ui| {
                ui.spinner();
                ui.label("sending the update…");
            });
        }
        if let Some(answer) = &self.updates.answer
            && answer_ui(ui, answer, "run-update-answer")
        {
            self.updates.answer = None;
        }
        if let Some(problem) = &self.updates.plan_problem {
            ui.colored_label(refused_colour(), problem);
        }
        list_ui(ui, mission);
    }
}

/// What the repair card says of the plan's default: the option it applies by itself and, when
/// the contingency gives the operator time, in how many seconds of run time from `run_secs`
/// (rounded up, so that "in 0 s" never shows while there is still time).
fn default_text(option: Option<u32>, at_run_secs: Option<f64>, run_secs: f64) -> String {
    match (option, at_run_secs) {
        (Some(number), Some(at)) if at > run_secs => format!(
            "Option {number} applies by itself in {:.0} s, unless you choose first.",
            (at - run_secs).ceil()
        ),
        (Some(number), Some(_)) => format!("Option {number} applies by itself now."),
        (Some(number), None) => format!("The plan applies option {number} by itself."),
        (None, _) => "The mission holds until you choose an option (or send a plan).".to_owned(),
    }
}
