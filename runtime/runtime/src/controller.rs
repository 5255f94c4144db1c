//! The mission controller inside `armor run`: plays the mission's Petri net on the run clock.
//! Module reports fire transitions at once (the supervisor hands them over as they arrive);
//! delays and dates wake the supervisor's loop at the right moment. What a firing starts and
//! stops, and the parameters of the marked places, reach the modules through the config server.

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::path::Path;
use std::time::{Duration, Instant};

use armor_model::net::{Engine, EngineError, EventRef, Firing, Marking, MissionNet, Place};
use armor_model::system::Reason;
use armor_module_api::Clock;
use serde_json::json;

use crate::config_server::{ConfigServer, Control};
use armor_protocol::{Enabled, FiringRecord, MissionStatus, Request, UpdateRecord};

/// How a mission ended.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    Complete,
    Aborted,
    Deadlock {
        marking: String,
    },
    Failed {
        module: String,
    },
    /// Only an operator could take the mission on (a leg held), and nobody did within the
    /// run's hold timeout.
    Unattended {
        marking: String,
        waited_secs: f64,
    },
}

impl Outcome {
    /// The word the report uses: `complete`, `aborted`, `deadlock` or `failed`.
    pub fn as_str(&self) -> &'static str {
        match self {
            Outcome::Complete => "complete",
            Outcome::Aborted => "aborted",
            Outcome::Deadlock { .. } => "deadlock",
            Outcome::Failed { .. } => "failed",
            Outcome::Unattended { .. } => "unattended",
        }
    }
}

/// A plan update being taken, as the controller records it.
pub struct Update<'a> {
    /// The file the operator sent, as named.
    pub file: &'a str,
    /// What it does, in one sentence.
    pub message: &'a str,
    /// More for the timeline's entry (the legs done, the places before and after).
    pub details: serde_json::Value,
    /// An event the new net hears at once, before the modules are told: the navigation's
    /// `blocked` when an area reported leaves the leg in force no way, so that the follower
    /// never takes a path through the area.
    pub event: Option<String>,
}

pub struct Controller {
    net: MissionNet,
    engine: Engine,
    clock: Clock,
    controllable: BTreeSet<String>,
    /// The modules that every place runs with the same parameters: never restarted.
    steady: BTreeSet<String>,
    paused: bool,
    outcome: Option<Outcome>,
    /// Kept only when a report was asked for, and then at most [`MAX_TIMELINE`] entries: a
    /// looping mission fires forever.
    timeline: Option<Vec<serde_json::Value>>,
    timeline_dropped: usize,
    /// The latest firings, for the status, and how many there were.
    recent: VecDeque<FiringRecord>,
    firings_total: usize,
    /// Each transition's first firing and each place's first marking, in run seconds (one entry
    /// per element of the net at most).
    first_fired: BTreeMap<String, f64>,
    first_marked: BTreeMap<String, f64>,
    /// Which modules ran and why when last noted in the timeline.
    running: BTreeMap<String, String>,
    /// How long the mission may wait for an operator alone (real time) before the run ends;
    /// `None`: as long as it takes.
    hold_timeout: Option<Duration>,
    /// Since when (real time) only an operator can take the mission on.
    held_since: Option<Instant>,
    /// The plan updates asked for, taken or refused, numbered from 1.
    updates: Vec<UpdateRecord>,
    /// The repair proposed while a leg cannot be completed.
    repair: Option<armor_protocol::Repair>,
    /// The leg being driven and its numbers, as the run's progress line last found them.
    progress: Option<armor_protocol::LegProgress>,
    /// Where every update and repair entry of the timeline goes too, as JSON (the run's node
    /// publishes it for the recording), report or not.
    records: Option<std::sync::mpsc::Sender<String>>,
    /// Since when (run seconds) the team bridge says the operator's link is lost.
    link_lost_since: Option<f64>,
    /// The `link.lost.SECS` already reported in this outage, by their seconds.
    link_reported: BTreeSet<u32>,
}

/// The modules that every place of `net` runs, each with the same parameters in all: a plan's
/// `<throughout>` (a recorder). Nothing tells one place's run of such a module from another's, so
/// it runs the whole mission in one go (one recording, not one per place).
fn steady_modules(net: &MissionNet) -> BTreeSet<String> {
    let Some((first, rest)) = net.places.split_first() else {
        return BTreeSet::new();
    };
    first
        .modules
        .iter()
        .filter(|module| {
            let params = params_of(first, module);
            rest.iter()
                .all(|place| place.modules.contains(module) && params_of(place, module) == params)
        })
        .cloned()
        .collect()
}

/// The parameters a place gives a module, sorted.
fn params_of<'a>(place: &'a Place, module: &str) -> Vec<(&'a str, &'a str)> {
    let mut params: Vec<(&str, &str)> = place
        .params
        .iter()
        .filter(|param| param.module == module)
        .map(|param| (param.name.as_str(), param.value.as_str()))
        .collect();
    params.sort_unstable();
    params
}

/// The most firings a status carries (the latest).
const RECENT_FIRINGS: usize = 200;

/// The most timeline entries a report keeps (the first ones; later ones are counted).
pub const MAX_TIMELINE: usize = 100_000;

impl Controller {
    /// Starts the net in its initial marking, now. `epoch_unix_secs` is the Unix time of run
    /// time 0, against which the net's absolute dates are compared. The timeline (for
    /// [`Controller::write_report`]) is kept only with `keep_timeline`.
    pub fn new(
        net: MissionNet,
        controllable: BTreeSet<String>,
        clock: Clock,
        epoch_unix_secs: f64,
        keep_timeline: bool,
    ) -> Self {
        let engine = Engine::start_at(&net, clock.now_secs()).with_date_origin(epoch_unix_secs);
        let mut controller = Self {
            steady: steady_modules(&net),
            net,
            engine,
            clock,
            controllable,
            paused: false,
            outcome: None,
            timeline: keep_timeline.then(Vec::new),
            timeline_dropped: 0,
            recent: VecDeque::new(),
            firings_total: 0,
            first_fired: BTreeMap::new(),
            first_marked: BTreeMap::new(),
            running: BTreeMap::new(),
            hold_timeout: None,
            held_since: None,
            updates: Vec::new(),
            repair: None,
            progress: None,
            records: None,
            link_lost_since: None,
            link_reported: BTreeSet::new(),
        };
        let at = controller.clock.now_secs();
        controller.first_marked = controller
            .engine
            .marking()
            .into_keys()
            .map(|place| (place, at))
            .collect();
        controller.record("started", json!({ "marking": controller.engine.marking() }));
        controller
    }

    /// Ends the mission (as [`Outcome::Unattended`]) once it has waited this long (real time)
    /// for an operator alone, such as a leg held after the robot was blocked; `None`: it waits
    /// as long as it takes.
    pub fn with_hold_timeout(mut self, hold_timeout: Option<Duration>) -> Self {
        self.hold_timeout = hold_timeout;
        self
    }

    /// Sends every update and repair entry of the timeline to `records` too, as JSON.
    pub fn set_records(&mut self, records: Option<std::sync::mpsc::Sender<String>>) {
        self.records = records;
    }

    /// The enabled transitions when only an operator can fire them (and at least one is
    /// enabled): what a held mission waits for.
    fn operator_choices(&self) -> Option<Vec<String>> {
        let enabled = self.engine.enabled();
        let only_operator = !enabled.is_empty()
            && enabled.iter().all(|name| {
                self.net.transition(name).is_some_and(|transition| {
                    let condition = &transition.condition;
                    condition.operator
                        && condition.event.is_none()
                        && condition.delay_secs.is_none()
                        && condition.at_unix_secs.is_none()
                })
            });
        only_operator.then_some(enabled)
    }

    /// Says once when the mission starts to wait for an operator alone, and ends it when the
    /// hold timeout has passed with no answer: a run with nobody at the controls must neither
    /// wait in silence nor for ever.
    fn watch_hold(&mut self) {
        if self.paused || self.outcome.is_some() {
            return;
        }
        let Some(choices) = self.operator_choices() else {
            self.held_since = None;
            return;
        };
        let marking = armor_model::net::marking_text(&self.engine.marking());
        match self.held_since {
            None => {
                self.held_since = Some(Instant::now());
                let fire = choices
                    .iter()
                    .map(|name| format!("`armor ctl fire {name}`"))
                    .collect::<Vec<_>>()
                    .join(" or ");
                let ending = match self.hold_timeout {
                    Some(timeout) => format!(
                        "without an answer the run ends in {} s (--hold-timeout)",
                        timeout.as_secs_f64()
                    ),
                    None => "the run waits as long as it takes (--hold-timeout 0)".to_owned(),
                };
                tracing::warn!(
                    "mission `{}` waits for the operator in {marking}: {fire}, or `armor ctl \
                     abort`; {ending}",
                    self.net.name
                );
                self.record("waiting_for_operator", json!({ "enabled": choices }));
            }
            Some(since) => {
                let waited = since.elapsed();
                if self.hold_timeout.is_some_and(|timeout| waited >= timeout) {
                    self.record("unattended", json!({ "marking": self.engine.marking() }));
                    self.outcome = Some(Outcome::Unattended {
                        marking,
                        waited_secs: waited.as_secs_f64(),
                    });
                }
            }
        }
    }

    /// What the modules must be told: who idles, and the parameters of the marked places.
    /// Paused, the mission's modules idle (the robot holds), but for those that run it through
    /// (a recorder records the pause too).
    ///
    /// The modules the marked places name are wanted, each for the first such place; what they
    /// need follows them (the config server closes the set).
    pub fn control(&self) -> Control {
        let mut wanted = BTreeMap::new();
        for place in self.engine.marking().into_keys() {
            let Some(place) = self.net.place(&place) else {
                continue;
            };
            for module in &place.modules {
                if !self.paused || self.steady.contains(module) {
                    wanted
                        .entry(module.clone())
                        .or_insert_with(|| format!("place {}", place.name));
                }
            }
        }
        Control {
            wanted: Some(wanted),
            held: BTreeSet::new(),
            overlays: self.engine.params(),
        }
    }

    pub fn outcome(&self) -> Option<&Outcome> {
        self.outcome.as_ref()
    }

    /// The net played (a plan update's once taken).
    pub fn net(&self) -> &MissionNet {
        &self.net
    }

    /// The places that hold tokens now.
    pub fn marking(&self) -> Marking {
        self.engine.marking()
    }

    /// The plan updates asked for so far, oldest first.
    pub fn updates(&self) -> &[UpdateRecord] {
        &self.updates
    }

    /// Moves the mission to `net` (an updated plan's), in `marking`, between two firings: what
    /// the two nets share of the enabled transitions keeps its timers (a delay goes on, a date is
    /// judged against the run's clock as always), the events latched so far with `keep_events`
    /// only. The modules are told what changed at once (the follower takes a new path or goal
    /// live, without a restart), then whatever can fire in the new net fires. The update is
    /// numbered and recorded with `details`; its number is returned.
    pub fn update(
        &mut self,
        net: MissionNet,
        marking: &Marking,
        keep_events: bool,
        update: Update<'_>,
        server: &ConfigServer,
    ) -> Result<u32, crate::update::Refused> {
        let Update {
            file,
            message,
            details,
            event,
        } = update;
        let now = self.clock.now_secs();
        let engine = Engine::resume(&net, marking, &self.engine, keep_events, now)
            .map_err(|err| format!("the updated net cannot start in {marking:?}: {err}"))?;
        self.engine = engine;
        self.steady = steady_modules(&net);
        self.net = net;
        self.held_since = None;
        for place in self.engine.marking().into_keys() {
            self.first_marked.entry(place).or_insert(now);
        }
        let (number, run_secs) = self.note_update(file, true, message);
        let mut entry = json!({
            "run_secs": run_secs,
            "number": number,
            "file": file,
            "taken": true,
            "message": message,
            "marking": self.engine.marking(),
        });
        if let (Some(entry), serde_json::Value::Object(details)) = (entry.as_object_mut(), details)
        {
            entry.extend(details);
        }
        self.record("update", entry);
        tracing::info!("plan update {number} ({file}) taken: {message}");
        if let Some(event) = event {
            let latched = self.engine.report_event(&event, now);
            self.record("event", json!({ "event": event, "latched_by": latched }));
            self.step(server);
        }
        self.tell(server);
        self.step(server);
        Ok(number)
    }

    /// Gives the mission `net`, the one it plays with other parameters (a leg's path planned
    /// again from where the robot is, before the operator's retry): the marking, the timers
    /// and the events latched go on; the modules are told when the next firing enters a place.
    pub fn reroute(&mut self, net: MissionNet) -> Result<(), EngineError> {
        let now = self.clock.now_secs();
        self.engine = Engine::resume(&net, &self.engine.marking(), &self.engine, true, now)?;
        self.net = net;
        Ok(())
    }

    /// The leg being driven with its numbers (`crate::progress::leg_progress`), for the status:
    /// the controller knows the net, the run's progress line where the robot is.
    pub fn set_progress(&mut self, progress: Option<armor_protocol::LegProgress>) {
        self.progress = progress;
    }

    /// The repair proposed (shown in the status), or none.
    pub fn set_repair(&mut self, repair: Option<armor_protocol::Repair>) {
        if let Some(repair) = &repair {
            self.record(
                "repair",
                serde_json::to_value(repair).unwrap_or(serde_json::Value::Null),
            );
        }
        self.repair = repair;
    }

    /// Records in the timeline what became of a repair (an option applied, or why not).
    pub fn note_repair(&mut self, details: serde_json::Value) {
        self.record("repair_applied", details);
    }

    /// Records a plan update refused, with `why`; the mission goes on unchanged. Its number is
    /// returned.
    pub fn refuse_update(&mut self, file: &str, why: &str) -> u32 {
        let (number, run_secs) = self.note_update(file, false, why);
        self.record(
            "update",
            json!({
                "run_secs": run_secs,
                "number": number,
                "file": file,
                "taken": false,
                "message": why,
            }),
        );
        tracing::warn!("plan update {number} ({file}) refused: {why}");
        number
    }

    /// Numbers an update and keeps it for the status and the report; its number and run time
    /// (the timeline's entry says the same time).
    fn note_update(&mut self, file: &str, taken: bool, message: &str) -> (u32, f64) {
        let number = u32::try_from(self.updates.len() + 1).unwrap_or(u32::MAX);
        let run_secs = self.clock.now_secs();
        self.updates.push(UpdateRecord {
            number,
            run_secs,
            file: file.to_owned(),
            taken,
            message: message.to_owned(),
        });
        (number, run_secs)
    }

    /// When the loop must wake for a delay or a date, if ever.
    pub fn next_wake(&self) -> Option<Instant> {
        if self.paused || self.outcome.is_some() {
            return None;
        }
        let (_, link) = self.due_link_events(self.clock.now_secs());
        let next = match (self.engine.next_deadline(), link) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        next.map(|run_secs| self.clock.instant_at(run_secs))
    }

    /// When each transition first fired and each place was first marked (run seconds): what a
    /// plan's summary reads its legs' times from.
    pub fn first_fired(&self) -> &BTreeMap<String, f64> {
        &self.first_fired
    }

    pub fn first_marked(&self) -> &BTreeMap<String, f64> {
        &self.first_marked
    }

    /// The transition that last marked `place`, among the recent firings: why a leg holds.
    pub fn last_fired_into(&self, place: &str) -> Option<&str> {
        self.recent.iter().rev().find_map(|firing| {
            let transition = self.net.transition(&firing.transition)?;
            transition
                .outputs
                .iter()
                .any(|arc| arc.place == place)
                .then_some(firing.transition.as_str())
        })
    }

    /// Fires `transition` (enabled, its condition not yet met) because the run forecasts what
    /// the condition waits for: a leg's `LEG_late`, once its arrival at the plan's speed comes
    /// after its deadline. Recorded as fired, with `forecast` saying why. Returns whether it
    /// fired.
    pub fn fire_forecast(
        &mut self,
        transition: &str,
        forecast: &str,
        server: &ConfigServer,
    ) -> bool {
        if self.net.transition(transition).is_none() {
            return false;
        }
        let before = self.engine.active_modules();
        let Ok(firing) = self.engine.fire_by_hand(transition, self.clock.now_secs()) else {
            return false;
        };
        self.remember(&firing, false);
        tracing::info!(
            "fired `{}` at {:.2} s ({forecast}) → {}",
            firing.transition,
            firing.at_secs,
            armor_model::net::marking_text(&firing.marking_after.to_marking())
        );
        self.record(
            "fired",
            json!({
                "transition": firing.transition,
                "at_secs": firing.at_secs,
                "forecast": forecast,
                "marking": firing.marking_after.to_marking(),
                "started": firing.started,
                "stopped": firing.stopped,
            }),
        );
        self.apply_firings(server, &before, std::slice::from_ref(&firing));
        self.step(server);
        true
    }

    fn remember(&mut self, firing: &Firing, by_hand: bool) {
        self.first_fired
            .entry(firing.transition.clone())
            .or_insert(firing.at_secs);
        for place in firing.marking_after.to_marking().into_keys() {
            self.first_marked.entry(place).or_insert(firing.at_secs);
        }
        if self.recent.len() == RECENT_FIRINGS {
            self.recent.pop_front();
        }
        self.recent.push_back(FiringRecord {
            run_secs: firing.at_secs,
            transition: firing.transition.clone(),
            by_hand,
        });
        self.firings_total += 1;
    }

    fn record(&mut self, kind: &str, details: serde_json::Value) {
        if let Some(records) = &self.records
            && matches!(kind, "update" | "repair" | "repair_applied")
        {
            let mut entry = json!({ "run_secs": self.clock.now_secs(), "kind": kind });
            if let (Some(entry), serde_json::Value::Object(details)) =
                (entry.as_object_mut(), &details)
            {
                entry.extend(details.clone());
            }
            // The node gone (the run ending) loses nothing the report does not keep.
            let _ = records.send(entry.to_string());
        }
        let Some(timeline) = &self.timeline else {
            return;
        };
        if timeline.len() >= MAX_TIMELINE {
            self.timeline_dropped += 1;
            return;
        }
        let mut entry = json!({ "run_secs": self.clock.now_secs(), "kind": kind });
        if let (Some(entry), serde_json::Value::Object(details)) = (entry.as_object_mut(), details)
        {
            entry.extend(details);
        }
        if let Some(timeline) = &mut self.timeline {
            timeline.push(entry);
        }
    }

    /// A module reported an event (`module.event`, or `module.<id>.failed` from the supervisor).
    pub fn on_event(&mut self, name: &str, server: &ConfigServer) {
        let now = self.clock.now_secs();
        let latched = self.engine.report_event(name, now);
        self.record("event", json!({ "event": name, "latched_by": latched }));
        if latched.is_empty() {
            tracing::debug!(event = name, "no enabled transition waits for this event");
        }
        self.step(server);
    }

    /// The team bridge says the link to the operator is lost (`lost`) or found again. While it
    /// is lost, each `link.lost.SECS` the net waits for is reported once its time has passed
    /// ([`Controller::step`]), once per outage.
    fn on_link(&mut self, lost: bool, server: &ConfigServer) -> (bool, String) {
        let now = self.clock.now_secs();
        match (lost, self.link_lost_since) {
            (true, Some(_)) => (true, "the link was lost already".to_owned()),
            (true, None) => {
                self.link_lost_since = Some(now);
                self.record("link_lost", json!({}));
                tracing::warn!("the link to the operator is lost: the mission goes on as planned");
                self.step(server);
                (
                    true,
                    "link lost: the mission goes on as its plan says".to_owned(),
                )
            }
            (false, None) => (true, "the link was up already".to_owned()),
            (false, Some(since)) => {
                self.link_lost_since = None;
                self.link_reported.clear();
                self.record("link_found", json!({ "lost_secs": now - since }));
                tracing::info!(
                    "the link to the operator is back after {:.0} s",
                    now - since
                );
                (true, format!("link found again after {:.0} s", now - since))
            }
        }
    }

    /// The `link.lost.SECS` events of the net whose time has come in this outage and that
    /// were not reported yet; and when the next one's comes.
    fn due_link_events(&self, now_secs: f64) -> (Vec<u32>, Option<f64>) {
        let Some(since) = self.link_lost_since else {
            return (Vec::new(), None);
        };
        let mut due = Vec::new();
        let mut next: Option<f64> = None;
        for transition in &self.net.transitions {
            let Some(EventRef::LinkLost { after_secs }) = transition
                .condition
                .event
                .as_deref()
                .and_then(EventRef::parse)
            else {
                continue;
            };
            if self.link_reported.contains(&after_secs) || due.contains(&after_secs) {
                continue;
            }
            let at = since + f64::from(after_secs);
            if at <= now_secs {
                due.push(after_secs);
            } else {
                next = Some(next.map_or(at, |next| next.min(at)));
            }
        }
        (due, next)
    }

    /// A module died for good: the mission hears `module.<id>.failed`; if nothing in the net
    /// waits for it while the module is needed, the mission cannot go on.
    pub fn on_failed(&mut self, module: &str, server: &ConfigServer) {
        let event = format!("module.{module}.failed");
        let latched = self.engine.report_event(&event, self.clock.now_secs());
        self.record("failed", json!({ "module": module, "latched_by": latched }));
        // Needed: named by a marked place, or pulled in by what such a module needs.
        let needed = self.engine.active_modules().contains(module)
            || server
                .demand()
                .get(module)
                .is_some_and(|reason| matches!(reason, Reason::NeededBy(_) | Reason::Carries(_)));
        self.step(server);
        if latched.is_empty() && needed && self.outcome.is_none() {
            self.outcome = Some(Outcome::Failed {
                module: module.to_owned(),
            });
        }
    }

    /// Fires whatever can fire now and tells the modules.
    pub fn step(&mut self, server: &ConfigServer) {
        if self.paused || self.outcome.is_some() {
            return;
        }
        let now = self.clock.now_secs();
        let (due, _) = self.due_link_events(now);
        for after_secs in due {
            let event = armor_model::net::link_lost_event(after_secs);
            let latched = self.engine.report_event(&event, now);
            self.record("event", json!({ "event": event, "latched_by": latched }));
            self.link_reported.insert(after_secs);
        }
        let before = self.engine.active_modules();
        let firings = self.engine.step(self.clock.now_secs());
        for firing in &firings {
            self.remember(firing, false);
            tracing::info!(
                "fired `{}` at {:.2} s → {}{}{}",
                firing.transition,
                firing.at_secs,
                armor_model::net::marking_text(&firing.marking_after.to_marking()),
                listed("; started", &firing.started),
                listed("; stopped", &firing.stopped),
            );
            self.record(
                "fired",
                json!({
                    "transition": firing.transition,
                    "at_secs": firing.at_secs,
                    "marking": firing.marking_after.to_marking(),
                    "started": firing.started,
                    "stopped": firing.stopped,
                }),
            );
        }
        if !firings.is_empty() {
            self.apply_firings(server, &before, &firings);
        }
        if self.engine.is_final() {
            tracing::info!(
                "mission `{}` complete: {}",
                self.net.name,
                armor_model::net::marking_text(&self.engine.marking())
            );
            self.record("complete", json!({ "marking": self.engine.marking() }));
            self.outcome = Some(Outcome::Complete);
        } else if self.engine.is_dead() {
            let marking = armor_model::net::marking_text(&self.engine.marking());
            tracing::error!("mission `{}` is deadlocked in {marking}", self.net.name);
            self.record("deadlock", json!({ "marking": self.engine.marking() }));
            self.outcome = Some(Outcome::Deadlock { marking });
        }
        self.watch_hold();
    }

    /// Tells the modules what `firings` changed, `before` being the modules active before them.
    ///
    /// Entering a place starts its modules afresh, even one that was already active in the place
    /// just left: two legs in a row drive the same follower, and each must report its own
    /// `goal_reached`. The config server sends a module only what changed for it, so a second
    /// leg with the same goal would otherwise reach the follower as nothing at all, and the
    /// mission would wait for ever. Such modules are stopped, then started again. A module that
    /// every place runs alike (see [`steady_modules`]) goes on, and so does one that a switch on
    /// a module's failure (`module.ID.failed`) leaves and enters with the same parameters.
    fn apply_firings(
        &mut self,
        server: &ConfigServer,
        before: &BTreeSet<String>,
        firings: &[Firing],
    ) {
        let after = self.engine.active_modules();
        let mut entered_again = BTreeSet::new();
        for transition in firings
            .iter()
            .filter_map(|firing| self.net.transition(&firing.transition))
        {
            // A switch on a failure (a plan's alternative, `module.ID.failed`) is no new step
            // of the work: a module that both sides run alike goes on where it is (the
            // follower keeps driving the same leg rather than start its path again).
            let on_failure =
                transition.condition.event.as_deref().is_some_and(|event| {
                    event.starts_with("module.") && event.ends_with(".failed")
                });
            let left: Vec<&Place> = transition
                .inputs
                .iter()
                .filter_map(|arc| self.net.place(&arc.place))
                .collect();
            for place in transition
                .outputs
                .iter()
                .filter_map(|arc| self.net.place(&arc.place))
            {
                for module in &place.modules {
                    let goes_on = on_failure
                        && left.iter().any(|from| {
                            from.modules.contains(module)
                                && params_of(from, module) == params_of(place, module)
                        });
                    if self.controllable.contains(module)
                        && before.contains(module)
                        && after.contains(module)
                        && !self.steady.contains(module)
                        && !goes_on
                    {
                        entered_again.insert(module.clone());
                    }
                }
            }
        }
        if !entered_again.is_empty() {
            tracing::info!(modules = ?entered_again, "restarting the modules of a place entered");
            let mut control = self.control();
            control.held.extend(entered_again);
            server.set_control(control);
        }
        self.tell(server);
    }

    /// Puts the mission's wishes in force, and records in the timeline which modules run and
    /// why when that changed.
    fn tell(&mut self, server: &ConfigServer) {
        server.set_control(self.control());
        self.note_demand(server);
    }

    /// Records in the timeline which modules run and why, if that changed since last noted
    /// (the operator's hand changes it too).
    pub fn note_demand(&mut self, server: &ConfigServer) {
        let running: BTreeMap<String, String> = server
            .demand()
            .into_iter()
            .map(|(module, reason)| (module, reason.to_string()))
            .collect();
        if running != self.running {
            self.record("demand", json!({ "running": running }));
            self.running = running;
        }
    }

    pub fn status(&self) -> MissionStatus {
        MissionStatus {
            name: self.net.name.clone(),
            paused: self.paused,
            marking: self.engine.marking(),
            enabled: self
                .engine
                .enabled()
                .into_iter()
                .map(|name| self.waits_for(name))
                .collect(),
            active_modules: self.engine.active_modules().into_iter().collect(),
            firings: self.recent.iter().cloned().collect(),
            firings_total: self.firings_total,
            outcome: self
                .outcome
                .as_ref()
                .map(|outcome| outcome.as_str().to_owned()),
            updates: self.updates.clone(),
            repair: self.repair.clone(),
            progress: self.progress.clone(),
        }
    }

    /// What an enabled transition waits for: its event, the rest of its delay, its date, the
    /// operator.
    fn waits_for(&self, name: String) -> Enabled {
        let mut waits_for = Vec::new();
        if let Some(transition) = self.net.transition(&name) {
            let now = self.clock.now_secs();
            if let Some(event) = &transition.condition.event
                && !self.engine.event_latched(&name)
            {
                waits_for.push(event.clone());
            }
            if let (Some(delay), Some(since)) = (
                transition.condition.delay_secs,
                self.engine.enabled_since(&name),
            ) {
                let left = since + delay - now;
                if left > 0.0 {
                    waits_for.push(format!("{left:.1} s"));
                }
            }
            if let Some(at) = transition.condition.at_unix_secs {
                let left = at - self.engine.date_origin() - now;
                if left > 0.0 {
                    waits_for.push(format!("its date, in {left:.1} s"));
                }
            }
            if transition.condition.operator {
                waits_for.push("the operator".to_owned());
            }
        }
        Enabled {
            transition: name,
            waits_for,
        }
    }

    /// Answers an operator's request about the mission: whether it was done, and what was.
    pub fn handle(&mut self, request: Request, server: &ConfigServer) -> (bool, String) {
        match request {
            Request::Status
            | Request::StartModule { .. }
            | Request::StopModule { .. }
            | Request::ReleaseModule { .. }
            | Request::Teleop { .. }
            | Request::SetPose { .. }
            | Request::Update { .. }
            | Request::Area { .. }
            | Request::Repair { .. }
            | Request::Files => (false, "not a mission request".to_owned()),
            Request::Link { lost } => self.on_link(lost, server),
            Request::Pause if self.paused => (false, "already paused".to_owned()),
            Request::Pause => {
                self.paused = true;
                // An operator is there: a new wait for one is timed afresh after the resume.
                self.held_since = None;
                self.tell(server);
                self.record("paused", json!({}));
                tracing::info!("mission paused by the operator");
                (true, "paused: controllable modules hold".to_owned())
            }
            Request::Resume if !self.paused => (false, "not paused".to_owned()),
            Request::Resume => {
                self.paused = false;
                self.tell(server);
                self.record("resumed", json!({}));
                tracing::info!("mission resumed by the operator");
                self.step(server);
                (true, "resumed".to_owned())
            }
            Request::Abort => {
                self.record("aborted", json!({ "marking": self.engine.marking() }));
                tracing::warn!("mission aborted by the operator");
                self.outcome = Some(Outcome::Aborted);
                (true, "aborted".to_owned())
            }
            Request::Fire { transition } => {
                let before = self.engine.active_modules();
                match self.engine.fire_by_hand(&transition, self.clock.now_secs()) {
                    Ok(firing) => {
                        self.remember(&firing, true);
                        tracing::info!(
                            "operator fired `{}` → {}",
                            firing.transition,
                            armor_model::net::marking_text(&firing.marking_after.to_marking())
                        );
                        self.record(
                            "fired",
                            json!({
                                "transition": firing.transition,
                                "by_hand": true,
                                "marking": firing.marking_after.to_marking(),
                                "started": firing.started,
                                "stopped": firing.stopped,
                            }),
                        );
                        self.apply_firings(server, &before, std::slice::from_ref(&firing));
                        self.step(server);
                        (true, format!("fired `{transition}`"))
                    }
                    Err(err) => (false, err.to_string()),
                }
            }
        }
    }

    /// Writes the timeline as JSON.
    /// Writes the report: the outcome, the timeline, the behaviours' state changes (as the
    /// control interface gives them) and, for a simulated plan run, the rehearsal's verdict by
    /// the simulator's truth (`crate::rehearsal::report`).
    pub fn write_report(
        &self,
        file: &Path,
        behaviour_changes: &[armor_protocol::BehaviourChange],
        rehearsal: Option<&serde_json::Value>,
    ) -> std::io::Result<()> {
        let mut report = json!({
            "mission": self.net.name,
            "outcome": self.outcome.as_ref().map_or("unfinished", Outcome::as_str),
            "timeline": self.timeline.as_deref().unwrap_or_default(),
            "timeline_dropped": self.timeline_dropped,
            "behaviour_changes": behaviour_changes,
            "updates": self.updates,
        });
        if let Some(rehearsal) = rehearsal {
            report["rehearsal"] = rehearsal.clone();
        }
        let text = serde_json::to_string_pretty(&report).map_err(std::io::Error::other)?;
        crate::fs::write_atomically(file, text.as_bytes())
    }
}

fn listed(label: &str, names: &[String]) -> String {
    if names.is_empty() {
        String::new()
    } else {
        format!("{label} {}", names.join(", "))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn steady(places: &str) -> BTreeSet<String> {
        let text = format!(r#"<mission name="m" system="s.xml">{places}</mission>"#);
        let net = MissionNet::parse(&text).expect("a valid net");
        steady_modules(&net)
    }

    #[test]
    fn a_pause_idles_every_module_of_the_mission_but_the_steady_ones() {
        let recorder = r#"<module name="recorder"/>"#;
        let text = format!(
            r#"<mission name="m" system="s.xml">
                 <place name="one" tokens="1"><module name="follower"/>{recorder}</place>
                 <place name="done" final="true">{recorder}</place>
               </mission>"#
        );
        let net = MissionNet::parse(&text).expect("a valid net");
        let controllable = ["follower", "recorder", "sim"].map(str::to_owned).into();
        let mut controller = Controller::new(net, controllable, Clock::real_time(), 0.0, false);
        let wanted = |modules: &[&str]| {
            Some(
                modules
                    .iter()
                    .map(|module| ((*module).to_owned(), "place one".to_owned()))
                    .collect(),
            )
        };
        assert_eq!(
            controller.control().wanted,
            wanted(&["follower", "recorder"])
        );
        controller.paused = true;
        assert_eq!(controller.control().wanted, wanted(&["recorder"]));
    }

    #[test]
    fn each_link_lost_time_comes_once_an_outage_from_when_the_link_was_lost() {
        let net = MissionNet::parse(
            r#"<mission name="m" system="s.xml">
                 <place name="one" tokens="1"/><place name="held"/><place name="back"/>
                 <transition name="hold" event="link.lost.3"><input place="one"/><output place="held"/></transition>
                 <transition name="home" event="link.lost.5"><input place="one"/><output place="back"/></transition>
               </mission>"#,
        )
        .expect("a valid net");
        let mut controller = Controller::new(net, BTreeSet::new(), Clock::real_time(), 0.0, false);
        assert_eq!(controller.due_link_events(100.0), (vec![], None));
        controller.link_lost_since = Some(100.0);
        assert_eq!(controller.due_link_events(101.0), (vec![], Some(103.0)));
        assert_eq!(controller.due_link_events(103.0), (vec![3], Some(105.0)));
        controller.link_reported.insert(3);
        assert_eq!(controller.due_link_events(104.0), (vec![], Some(105.0)));
        assert_eq!(controller.due_link_events(200.0), (vec![5], None));
        controller.link_reported.insert(5);
        assert_eq!(controller.due_link_events(300.0), (vec![], None));
    }

    #[test]
    fn a_module_every_place_runs_alike_is_steady() {
        let recorder =
            r#"<module name="recorder"/><param module="recorder" name="file" value="a.mcap"/>"#;
        let places = format!(
            r#"<place name="one" tokens="1"><module name="follower"/>{recorder}
                 <param module="follower" name="goal_x_m" value="1"/></place>
               <place name="two"><module name="follower"/>{recorder}
                 <param module="follower" name="goal_x_m" value="1"/></place>
               <place name="done" final="true">{recorder}</place>"#
        );
        // The follower is not in the final place: restarted at each leg, even with one goal.
        assert_eq!(steady(&places), BTreeSet::from(["recorder".to_owned()]));
        // Another file in one place: each place's recording is its own.
        let other_file = places.replacen("a.mcap", "b.mcap", 1);
        assert!(steady(&other_file).is_empty());
        // A place without the recorder: it stops there, and starts afresh after.
        let without = format!(
            r#"<place name="one" tokens="1">{recorder}</place><place name="wait"/>
               <place name="two">{recorder}</place>"#
        );
        assert!(steady(&without).is_empty());
    }
}
