//! From the run to a client: the replies, with the run's state and files.

use armor_model::net::Marking;
use armor_module_api::protocol::NodeStats;
use serde::{Deserialize, Serialize};

/// The module type whose command port the run's teleop relay drives.
pub const TELEOP_TYPE: &str = "teleop";
/// The endpoint name the teleop module says it listens at ([`ModuleStatus::endpoints`]).
pub const TELEOP_ENDPOINT: &str = "teleop";

/// A run's state: every module, and the mission if there is one.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Status {
    pub system: String,
    pub run_secs: f64,
    pub time_scale: f64,
    /// The agent's address, for a client that wants to subscribe to the run's data.
    pub agent: String,
    pub modules: Vec<ModuleStatus>,
    pub mission: Option<MissionStatus>,
    /// The latest changes of behaviour states, oldest first (the run keeps a bounded number).
    #[serde(default)]
    pub behaviour_changes: Vec<BehaviourChange>,
}

/// A module's behaviour state changed (`state` none: it went away).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BehaviourChange {
    pub run_secs: f64,
    pub module: String,
    pub state: Option<BehaviourState>,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MissionStatus {
    pub name: String,
    pub paused: bool,
    pub marking: Marking,
    /// Transitions that may fire now or later, each with what it waits for.
    pub enabled: Vec<Enabled>,
    pub active_modules: Vec<String>,
    /// The latest firings, oldest first, and how many there were in all.
    pub firings: Vec<FiringRecord>,
    pub firings_total: usize,
    /// `complete`, `aborted`, `deadlock` or `failed` once the mission has ended.
    pub outcome: Option<String>,
    /// The plan updates asked for (`armor ctl update`), taken or refused, oldest first.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub updates: Vec<UpdateRecord>,
    /// What the mission proposes while a leg cannot be completed as planned (blocked, or cut by
    /// a no-go area); none when nothing is contradicted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub repair: Option<Repair>,
    /// How the leg being driven stands, as `armor run`'s live line gives it; none when no leg
    /// is being driven (before the first sets off, between legs, after the last) or the run
    /// plays a mission net rather than a plan.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub progress: Option<LegProgress>,
}

/// The leg being driven: how far it has to go and how it stands against its deadline. The
/// same numbers make `armor run`'s live line and the studio's Run view.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LegProgress {
    /// Its number, from 1, among `legs` in the plan.
    pub number: usize,
    pub legs: usize,
    pub leg: String,
    pub from: String,
    pub to: String,
    /// The distance left on its planned path from where the robot believes it is (metres);
    /// none while its odometry is not known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub left_m: Option<f64>,
    /// Its deadline (`arrive_by`, run seconds), if it has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub deadline_run_secs: Option<f64>,
    /// The time left to that deadline (seconds; negative once late).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_left_secs: Option<f64>,
    /// The time left less the time the distance left takes at the plan's speed (seconds):
    /// positive, the robot is early by that much; negative, late.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slack_secs: Option<f64>,
}

/// A repair the mission proposes when the world contradicts the plan: a leg cannot be completed
/// (the navigation is `blocked`, a no-go area reported cuts the route of the leg in force or of
/// a later one), or not in time (its deadline passed: `late`). Each option is a plan update; `armor ctl repair N` ([`crate::Request::Repair`])
/// applies one, and the plan's `<contingency on="blocked" do="repair"/>` applies the default
/// (`docs/plans.md`, "Repair").
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Repair {
    /// When it was proposed (run seconds).
    pub run_secs: f64,
    /// The leg that cannot be completed as planned.
    pub leg: String,
    /// Why, in words (``blocked in `cross_drive` ``, ``no-go area `mines` cuts leg `north` ``).
    pub why: String,
    /// The options, best first, numbered from 1.
    pub options: Vec<RepairOption>,
    /// The number of the option the plan's contingency applies by itself, if it names one
    /// (`do="repair"`: the best); none: the mission waits for the operator's choice.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub default_option: Option<u32>,
    /// When the default is applied unless the operator chooses first (run seconds), when the
    /// contingency gives the operator time (`after_secs`); none: at once.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub default_at_run_secs: Option<f64>,
}

/// What a repair option does.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RepairKind {
    /// Drive to the leg's destination round through another waypoint of the plan.
    #[default]
    WayRound,
    /// Give up the leg's destination and drive on from where the robot is to the next leg's.
    Skip,
    /// Stay where the robot is until an area is lifted (an update) or the operator decides.
    Wait,
    /// Drive back to where the plan starts, and end there.
    Return,
    /// A late leg's deadline moved to when the robot is now expected there.
    PushBack,
    /// A late leg's deadline given up: it drives on with none.
    DropDeadline,
}

impl RepairKind {
    pub fn as_str(self) -> &'static str {
        match self {
            RepairKind::WayRound => "way round",
            RepairKind::Skip => "skip",
            RepairKind::Wait => "wait",
            RepairKind::Return => "return",
            RepairKind::PushBack => "push back",
            RepairKind::DropDeadline => "drop deadline",
        }
    }
}

/// One repair option, with its costs against what is left of the plan.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RepairOption {
    /// Its number, from 1, as `armor ctl repair N` names it.
    pub number: u32,
    pub kind: RepairKind,
    /// What it does, in one sentence (``round through `north`, then `east` ``).
    pub summary: String,
    /// The waypoints it drives through to the rest of the plan, in order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub via: Vec<String>,
    /// The legs whose destination it gives up.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub legs_dropped: Vec<String>,
    /// The distance left to drive, from where the robot is to the end of the plan so repaired
    /// (metres, along the planned paths).
    pub distance_m: f64,
    /// The time that takes at the plan's speed, with the arrivals' and waits' times (seconds);
    /// none for a wait, which lasts as long as it has to.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub duration_secs: Option<f64>,
    /// The deadlines (`arrive_by`) it misses, a sentence each (``leg `east` due by 08:05:00,
    /// arrives 08:06:12``).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub deadlines_missed: Vec<String>,
}

/// A plan update asked of a running mission, numbered from 1 in the order they came.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct UpdateRecord {
    pub number: u32,
    pub run_secs: f64,
    /// The file the operator sent, as named.
    pub file: String,
    /// Whether the mission moved to it.
    pub taken: bool,
    /// What it changed, or why it was refused.
    pub message: String,
}

/// An enabled transition and what it still waits for (an event, the rest of a delay, a date,
/// the operator); nothing when it fires at the next step.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Enabled {
    pub transition: String,
    pub waits_for: Vec<String>,
}

impl std::fmt::Display for Enabled {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.transition)?;
        if !self.waits_for.is_empty() {
            write!(f, " (waits for {})", self.waits_for.join(", "))?;
        }
        Ok(())
    }
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FiringRecord {
    pub run_secs: f64,
    pub transition: String,
    pub by_hand: bool,
}

/// A module's process and activity, as the run view's module monitor shows it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ModuleState {
    /// Its process is up, not yet configured.
    #[default]
    Starting,
    /// Configured and at work.
    Running,
    /// Configured and idle: the mission (or the operator) stopped it.
    Stopped,
    /// Its process died; it is started again after a backoff.
    Crashed,
    /// Started again after a crash, not yet configured.
    Restarting,
    /// Crashed too often (or with restart `never`): given up.
    Failed,
    /// Ended on its own, successfully.
    Exited,
    /// Stopped with the whole run (a monitor's word once the run is over: the run itself
    /// never reports it).
    Ended,
}

impl ModuleState {
    pub fn as_str(self) -> &'static str {
        match self {
            ModuleState::Starting => "starting",
            ModuleState::Running => "running",
            ModuleState::Stopped => "stopped",
            ModuleState::Crashed => "crashed",
            ModuleState::Restarting => "restarting",
            ModuleState::Failed => "failed",
            ModuleState::Exited => "exited",
            ModuleState::Ended => "ended with the run",
        }
    }
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ModuleStatus {
    pub name: String,
    pub module_type: String,
    pub state: ModuleState,
    /// Whether the mission (and the operator) can start and stop it.
    pub controllable: bool,
    /// The operator's hand on it: started (`true`) or stopped (`false`) until released.
    pub manual: Option<bool>,
    pub pid: Option<u32>,
    pub restarts: u32,
    /// How its process last ended, when it crashed (`was killed by signal 9`).
    pub last_exit: Option<String>,
    /// What it did so far, as of its last answer to a ping.
    pub stats: Option<NodeStats>,
    /// Why it runs (or would, once up): `place cross_drive`, `needed by follower.odometry`,
    /// `carries follower.cmd_desired`, `by hand`, `always`, `not controllable`, `no mission`;
    /// `None` when nothing needs it and it idles.
    #[serde(default)]
    pub why: Option<String>,
    /// A behaviour's state (`slept`, `checking`, `ready`, `winner`); none for a module that
    /// never said whether it applies.
    #[serde(default)]
    pub behaviour: Option<BehaviourState>,
    /// An arbiter's winner: the module whose command is in control.
    #[serde(default)]
    pub winner: Option<String>,
    /// The subsystems it is in, outermost first (empty: none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub subsystems: Vec<String>,
    /// The declared host it runs on (`armor host`), or `None` for the supervisor's machine.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub host: Option<String>,
    /// Where its own services listen, name → address, as it said (the teleop's `teleop`).
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub endpoints: std::collections::BTreeMap<String, String>,
}

/// A file of the run, as the run's machine has it.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct FileText {
    /// Its path on the run's machine (for messages: the client need not have it).
    pub path: String,
    pub text: String,
}

/// What a client needs to draw a run it did not start ([`Request::Files`]).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct RunFiles {
    /// The system file.
    pub system: FileText,
    /// The mission the run plays, a plan or a net, when it has one: a plan as it runs now,
    /// with the updates taken so far (written as the studio saves a plan), a net as its file is.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mission: Option<FileText>,
    /// The files the system's `file` parameters name (the simulated world), as the run found
    /// them.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub params: Vec<ParamFile>,
    /// The description of every module type the system uses, in the describe format
    /// (`docs/protocol.md`, section 5), so that a client without the module binaries knows
    /// their ports.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub descriptions: Vec<String>,
}

/// A file a module's parameter names.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ParamFile {
    pub module: String,
    pub param: String,
    pub file: FileText,
    /// The files it names in turn, by their names relative to its folder: a ROS map's image.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub beside: Vec<BinaryFile>,
}

/// A file that need not be text, its bytes in base64.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct BinaryFile {
    /// Its name as the file that names it writes it.
    pub name: String,
    pub base64: String,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Reply {
    pub ok: bool,
    pub message: String,
    pub status: Option<Status>,
    /// The answer to [`Request::Files`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub files: Option<RunFiles>,
}

/// A behaviour's state, as JDE's schemas have them. Modules that never said whether they
/// apply have none.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BehaviourState {
    /// Not activated (stopped by the mission or the operator).
    Slept,
    /// Active, its preconditions not met.
    Checking,
    /// Applicable, not chosen by an arbiter.
    Ready,
    /// Applicable and in control: an arbiter chose its command.
    Winner,
}

impl BehaviourState {
    pub fn as_str(self) -> &'static str {
        match self {
            BehaviourState::Slept => "slept",
            BehaviourState::Checking => "checking",
            BehaviourState::Ready => "ready",
            BehaviourState::Winner => "winner",
        }
    }
}

/// The answer to request `seq`.
#[derive(Debug, Serialize, Deserialize)]
pub struct FromRun {
    pub seq: u64,
    pub reply: Reply,
}
