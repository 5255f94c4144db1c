//! The Run view: start the current system or plan with the runtime of `armor run` and watch it.
//! The hierarchy oscilloscope ([`oscilloscope`]) lists every module in a tree, each arbiter with
//! its behaviours and their states, with its state, cycle time, rates and restarts and switches
//! to start and stop it by hand, over a time line of the behaviours' state changes; the mission
//! monitor shows the net with its live marking, what the enabled transitions wait for, the
//! firings so far, and the operator's buttons; the live map shows the robot (estimated and true
//! pose), its laser scan and the mapper's grid over the plan, the current leg highlighted, the
//! path the follower follows and the ones it replaced by replanning ([`followed`]), and each
//! module's markers in a layer with its switch ([`markers`]); any output can be inspected
//! ([`inspector`]); the operator drives through the teleop module from the keyboard or the
//! on-screen pad; each module's log is kept and filterable. A recording of the recorder opens
//! into the same map.

pub mod attach;
pub mod followed;
pub mod inspector;
pub mod live;
pub mod markers;
pub mod monitor;
pub mod oscilloscope;
pub mod progress;
pub mod prompt;
pub mod sensors_motors;
pub mod session;
pub mod untrusted;
pub mod updates;
pub mod video;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use armor_model::plan::Origin;
use armor_module_api::types::OccupancyGrid;
use armor_protocol::{ModuleState, Request, RunFiles, Status};
use egui::{Color32, RichText, Stroke, Ui};

use crate::common::context::ViewerContext;
use crate::common::draw::state_colour;
use crate::common::palette::Catalog;
use crate::mission::{LegRoute, MissionView};
use followed::FollowedLeg;
use live::{LiveData, Recording, Sources};
use session::{Level, RunOptions, RunSession};

/// The module type whose pose the set-pose tool sets (`armor ctl set-pose`).
const LOCALISER: &str = "localiser";
/// A set-pose drag shorter than this (points) gives no heading: it is not sent.
const SET_POSE_MIN_DRAG: f32 = 8.0;

/// Teleoperation speeds at full stick.
const DRIVE_MPS: f64 = 0.4;
const TURN_RADPS: f64 = 0.8;

/// What to run: the plan open in the Mission view, or the system.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Target {
    Plan(PathBuf),
    System(PathBuf),
}

impl Target {
    pub fn path(&self) -> &Path {
        match self {
            Target::Plan(path) | Target::System(path) => path,
        }
    }
}

pub struct RunView {
    pub session: Option<RunSession>,
    pub time_scale: f64,
    /// RFC 3339; empty for now (a plan's own start is offered).
    pub start_at: String,
    /// The shared secret's file for runs (`armor run --secret`); empty for none. Starts as
    /// `$ARMOR_SECRET_FILE`.
    pub secret_file: String,
    pub working_dir: PathBuf,
    pub module_path: Vec<PathBuf>,
    pub log_filter: String,
    /// Only this module's lines (all when `None`).
    pub log_module: Option<String>,
    pub log_min_level: Level,
    pub recording: Option<Recording>,
    /// The map of a run without a plan: an empty plan on the run's system.
    own_map: Option<(PathBuf, MissionView)>,
    grid_texture: Option<(u64, egui::TextureHandle)>,
    /// The teleoperation command held now, and when it was last sent.
    drive: (f64, f64),
    drive_sent: Option<Instant>,
    last_frame: Option<Instant>,
    /// Keep the map centred on the robot.
    pub follow: bool,
    /// Frame the plan's world (and so the robot) at the next frame: a run just started.
    fit_pending: bool,
    /// The mission's net was shown above the map at the last frame.
    net_shown: bool,
    /// Answers to the operator, newest last, shown in the status line by the app.
    pub messages: Vec<(bool, String)>,
    /// The follower's `max_replans` in the run's system (its value there, else its default).
    max_replans: Option<u32>,
    /// The follower's paths of the current leg, as drawn at the last frame.
    followed: FollowedLeg,
    pub video: video::VideoPanel,
    /// Modules whose markers' layer the user switched off.
    pub hidden_markers: BTreeSet<String>,
    /// The output the inspector shows.
    pub inspected: Option<String>,
    /// The moment the oscilloscope's time line is scrubbed to (`None`: now).
    pub timeline_at: Option<f64>,
    /// How many markers of each module the live map drew at the last frame (for tests).
    pub markers_drawn: BTreeMap<String, usize>,
    /// What the map drew at the last frame, for tests of its layout: every label's and tag's
    /// box (the plan's, the robots', the markers' texts), the robots' boxes, and the rectangle
    /// labels were kept in (the world's on screen).
    pub map_layout: MapLayout,
    /// Run → Attach…'s prompt, while it is open.
    pub attach_prompt: Option<attach::AttachPrompt>,
    /// The files of a run attached without its system file, written where the Run view reads
    /// them (kept as long as the attachment).
    attach_mirror: Option<attach::Mirror>,
    /// The set-pose tool is chosen: a press on the map is where the robot is, the drag its
    /// heading, the release sends it to the localiser (rviz's "2D Pose Estimate").
    pub set_pose_tool: bool,
    /// Where the set-pose press began (world frame), while the drag lasts.
    set_pose_from: Option<armor_model::world::Point>,
    /// The plan the run plays and its updates ([`updates`]).
    pub updates: updates::Updates,
}

impl RunView {
    pub fn new(module_path: Vec<PathBuf>) -> RunView {
        RunView {
            session: None,
            time_scale: 1.0,
            start_at: String::new(),
            secret_file: std::env::var(armor_module_api::auth::ENV_SECRET_FILE).unwrap_or_default(),
            working_dir: std::env::current_dir().unwrap_or_else(|_| PathBuf::from(".")),
            module_path,
            log_filter: String::new(),
            log_module: None,
            log_min_level: Level::Info,
            recording: None,
            own_map: None,
            grid_texture: None,
            drive: (0.0, 0.0),
            drive_sent: None,
            last_frame: None,
            follow: false,
            fit_pending: false,
            net_shown: false,
            messages: Vec::new(),
            max_replans: None,
            followed: FollowedLeg::default(),
            video: video::VideoPanel::default(),
            hidden_markers: BTreeSet::new(),
            inspected: None,
            timeline_at: None,
            markers_drawn: BTreeMap::new(),
            map_layout: MapLayout::default(),
            attach_prompt: None,
            attach_mirror: None,
            set_pose_tool: false,
            set_pose_from: None,
            updates: updates::Updates::default(),
        }
    }

    pub fn is_running(&self) -> bool {
        self.session.as_ref().is_some_and(RunSession::is_running)
    }

    /// Whether the studio may command the run: not with an observer's key.
    pub fn may_command(&self) -> bool {
        self.session
            .as_ref()
            .is_none_or(|session| session.shared().role != Some(armor_protocol::Role::Observer))
    }

    /// Whether the studio stopped watching a run started elsewhere (Detach): the run goes on,
    /// and what the studio saw of it last is no longer its state.
    pub fn is_detached(&self) -> bool {
        self.session
            .as_ref()
            .is_some_and(|session| session.is_attached() && !session.is_running())
    }

    /// The control address of the run attached to (or detached from).
    fn control_addr(&self) -> Option<std::net::SocketAddr> {
        self.session
            .as_ref()
            .and_then(|session| session.shared().control_addr)
    }

    /// Whether `path` is a copy of an attached run's files ([`attach::Mirror`]), not a document
    /// of the user's.
    pub fn is_mirror_copy(&self, path: &Path) -> bool {
        self.attach_mirror
            .as_ref()
            .is_some_and(|mirror| mirror.holds(path))
    }

    /// The last state the run reported (none once detached from it: the run goes on unseen);
    /// once the run is over, the modules it left at work
    /// read "ended with the run" (the run stopped them), and the crashed and failed stay so.
    pub fn status(&self) -> Option<Status> {
        if self.is_detached() {
            return None;
        }
        let session = self.session.as_ref()?;
        let mut status = session.shared().status.clone()?;
        if !session.is_running() && session.shared().ended.is_some() {
            for module in &mut status.modules {
                if matches!(
                    module.state,
                    ModuleState::Starting
                        | ModuleState::Running
                        | ModuleState::Stopped
                        | ModuleState::Restarting
                ) {
                    module.state = ModuleState::Ended;
                }
            }
        }
        Some(status)
    }

    /// The map of a run without a plan (an empty plan on the run's system), once drawn.
    pub fn own_map_view(&self) -> Option<&MissionView> {
        self.own_map.as_ref().map(|(_, mission)| mission)
    }

    /// Frames the world, the plan and the robot at the next frame (Fit, Home).
    pub fn request_fit(&mut self) {
        self.fit_pending = true;
    }

    /// The file the current (or last) run runs.
    pub fn session_target(&self) -> Option<&Path> {
        self.session
            .as_ref()
            .map(|session| session.options.target.as_path())
    }

    /// The live data shown (the run's, or the recording's).
    pub fn live(&self) -> LiveData {
        match (&self.session, &self.recording) {
            (_, Some(recording)) => recording.live.clone(),
            (Some(session), None) => live::lock(&session.shared().live).clone(),
            (None, None) => LiveData::default(),
        }
    }

    /// The lines `source` (a module's name, or `armor` for the supervisor) wrote to the
    /// current run's log so far, oldest first.
    pub fn log_of(&self, source: &str) -> Vec<String> {
        self.session.as_ref().map_or_else(Vec::new, |session| {
            session
                .shared()
                .logs
                .iter()
                .filter(|line| line.source == source)
                .map(|line| line.text.clone())
                .collect()
        })
    }

    /// The outputs the live views show: the recording's channels, or the run's outputs.
    pub fn sources(&self) -> Option<Sources> {
        match (&self.session, &self.recording) {
            (_, Some(recording)) => Some(recording.sources.clone()),
            (Some(session), None) => Some(session.options.sources.clone()),
            (None, None) => None,
        }
    }

    /// The follower's paths of the current leg drawn on the live map at the last frame: the one
    /// followed, those replaced by replans, and how many replans there were.
    pub fn followed(&self) -> &FollowedLeg {
        &self.followed
    }

    /// The size in pixels of the occupancy grid's picture last drawn on the live map.
    pub fn grid_picture_size(&self) -> Option<[usize; 2]> {
        self.grid_texture
            .as_ref()
            .map(|(_, texture)| texture.size())
    }

    /// How the run ended, once it has.
    pub fn ended(&self) -> Option<String> {
        self.session.as_ref().and_then(|s| s.shared().ended.clone())
    }

    /// A simulated plan run's verdict by the simulator's truth, once the run has ended.
    pub fn rehearsal(&self) -> Option<armor_model::rehearsal::Verdict> {
        self.session
            .as_ref()
            .and_then(|s| s.shared().rehearsal.clone())
    }

    /// Whether the run has a localiser whose pose can be set by hand: a module of that type, or
    /// (attached without the system) an output carrying its estimate.
    pub fn has_localiser(&self) -> bool {
        let by_status = self.status().is_some_and(|status| {
            status
                .modules
                .iter()
                .any(|module| module.module_type == LOCALISER)
        });
        by_status || self.sources().is_some_and(|s| s.estimate.is_some())
    }

    /// Starts a run of `target`; the caller saved it first. `mission` is the Mission view when
    /// a plan is open: its map and net are the run's.
    pub fn start(
        &mut self,
        target: Target,
        mission: Option<&MissionView>,
        catalog: &Catalog,
        ctx: &egui::Context,
    ) {
        let options = self.options(&target, mission, catalog, ctx);
        match RunSession::start(options, ctx) {
            Ok(session) => {
                self.messages
                    .push((true, format!("running {}", target.path().display())));
                self.session = Some(session);
                self.fit_pending = true;
                self.updates.restart(plan_of(&target));
            }
            Err(err) => self.messages.push((false, format!("{err:#}"))),
        }
    }

    /// Watches a run of `target` started elsewhere, through its control interface; with
    /// `ask_files`, asks it for its files too ([`Self::take_runs_files`]): the plan it plays.
    pub fn attach(
        &mut self,
        target: Target,
        control: std::net::SocketAddr,
        (mission, ask_files): (Option<&MissionView>, bool),
        catalog: &Catalog,
        ctx: &egui::Context,
    ) {
        let options = RunOptions {
            ask_files,
            ..self.options(&target, mission, catalog, ctx)
        };
        self.session = Some(RunSession::attach(options, control, ctx));
        self.messages
            .push((true, format!("watching the run at {control}")));
        self.updates.restart(plan_of(&target));
    }

    /// The files a run attached to has sent when asked (at most once per attachment), with
    /// its control address and whether the studio had its system file open: the window writes
    /// them out ([`attach::mirror`]) and attaches again with them ([`Self::keep_mirror`]).
    pub fn take_runs_files(&mut self) -> Option<(std::net::SocketAddr, RunFiles, bool)> {
        let session = self.session.as_ref()?;
        if !session.is_attached() || !session.options.ask_files {
            return None;
        }
        let mut shared = session.shared();
        let control = shared.control_addr?;
        let files = shared.files.take()?;
        Some((
            control,
            files,
            !session.options.target.as_os_str().is_empty(),
        ))
    }

    /// Keeps the folder of an attached run's files as long as the attachment.
    pub fn keep_mirror(&mut self, mirror: attach::Mirror) {
        self.fit_pending = true;
        self.attach_mirror = Some(mirror);
    }

    /// Watches a run started elsewhere whose system file the studio does not have: its
    /// modules, mission and controls at once, and the live map once the run has sent its files
    /// ([`Self::take_runs_files`]).
    pub fn attach_bare(&mut self, control: std::net::SocketAddr, ctx: &egui::Context) {
        self.stop();
        self.recording = None;
        let options = RunOptions {
            target: PathBuf::new(),
            time_scale: self.time_scale,
            start_at: None,
            working_dir: self.working_dir.clone(),
            module_path: self.module_path.clone(),
            sources: Sources::default(),
            secret: Some(PathBuf::from(self.secret_file.trim()))
                .filter(|file| !file.as_os_str().is_empty()),
            ask_files: true,
        };
        self.session = Some(RunSession::attach(options, control, ctx));
        self.messages
            .push((true, format!("watching the run at {control}")));
        self.updates.restart(None);
    }

    /// What a run of `target` needs: the sources of the live views from its system.
    fn options(
        &mut self,
        target: &Target,
        mission: Option<&MissionView>,
        catalog: &Catalog,
        ctx: &egui::Context,
    ) -> RunOptions {
        self.stop();
        self.recording = None;
        let system = match target {
            Target::Plan(_) => mission.and_then(|mission| mission.plan_system().cloned()),
            Target::System(path) => {
                let mission = self.own_map(path, catalog, ctx);
                mission.plan_system().cloned()
            }
        };
        let sources = system
            .as_ref()
            .map(|system| Sources::of(system, |t| catalog.get(t).cloned()))
            .unwrap_or_default();
        self.max_replans = system
            .as_ref()
            .zip(sources.path.as_deref())
            .and_then(|(system, path)| max_replans(system, path, catalog));
        let start_at = match self.start_at.trim() {
            "" => match (&target, mission) {
                (Target::Plan(_), Some(mission)) => mission
                    .plan()
                    .start_unix_secs
                    .map(armor_model::net::format_rfc3339),
                _ => None,
            },
            date => Some(date.to_owned()),
        };
        RunOptions {
            target: target.path().to_path_buf(),
            time_scale: self.time_scale,
            start_at: start_at.filter(|date| !date.is_empty()),
            working_dir: self.working_dir.clone(),
            module_path: self.module_path.clone(),
            sources,
            secret: Some(PathBuf::from(self.secret_file.trim()))
                .filter(|file| !file.as_os_str().is_empty()),
            ask_files: false,
        }
    }

    /// Asks the run to stop (its modules are stopped in order).
    pub fn stop(&mut self) {
        let detaching = self
            .session
            .as_ref()
            .is_some_and(|session| session.is_attached() && session.is_running());
        if let Some(session) = &mut self.session {
            session.stop();
        }
        if detaching {
            let at = self
                .control_addr()
                .map_or_else(String::new, |addr| format!(" at {addr}"));
            self.messages.push((
                true,
                format!("detached from the run{at}: it goes on without the studio"),
            ));
        }
    }

    /// Sends an operator request to the run.
    pub fn request(&mut self, request: Request) {
        match &self.session {
            Some(session) if session.is_running() => session.request(request),
            _ => self.messages.push((false, "no run".to_owned())),
        }
    }

    /// Opens a recording into the live map.
    pub fn open_recording(&mut self, file: &Path) {
        match Recording::open(file) {
            Ok(recording) => {
                self.messages.push((
                    true,
                    format!(
                        "{}: {} messages over {:.1} s",
                        file.display(),
                        recording.message_count(),
                        recording.duration_secs
                    ),
                ));
                self.recording = Some(recording);
            }
            Err(err) => self.messages.push((false, format!("{err:#}"))),
        }
    }

    fn own_map(
        &mut self,
        system: &Path,
        catalog: &Catalog,
        ctx: &egui::Context,
    ) -> &mut MissionView {
        if self
            .own_map
            .as_ref()
            .is_some_and(|(path, _)| path != system)
        {
            self.own_map = None;
        }
        &mut self
            .own_map
            .get_or_insert_with(|| {
                let mut mission = MissionView::new(ctx);
                mission.set_catalog(catalog);
                let _ = mission.new_plan(Some(system));
                (system.to_path_buf(), mission)
            })
            .1
    }

    /// Notices a run's end and collects answers; called every frame, whatever the view.
    pub fn poll(&mut self) {
        if let Some(session) = &mut self.session {
            if session.poll()
                && let Some(ended) = session.shared().ended.clone()
            {
                // `mission failed`, `rehearsal FAILED`: either is a failure.
                let failed = ended.to_lowercase().contains("fail");
                self.messages.push((!failed, format!("the run {ended}")));
            }
            let replies: Vec<_> = std::mem::take(&mut session.shared().replies);
            self.messages.extend(replies);
        }
    }

    /// The live state of each module, for the diagram's colours.
    pub fn module_states(&self) -> BTreeMap<String, ModuleState> {
        self.status()
            .filter(|_| self.is_running())
            .map(|status| {
                status
                    .modules
                    .iter()
                    .map(|module| (module.name.clone(), module.state))
                    .collect()
            })
            .unwrap_or_default()
    }

    // ----- The frame -----

    /// The view; `mission` is the Mission view when a plan is open, whose map and net the run
    /// is drawn on; `target` is what a Run would start (the document of the view left last).
    /// Returns the target to run when Run was clicked.
    pub fn ui(
        &mut self,
        ui: &mut Ui,
        viewer: &ViewerContext,
        mission: Option<&mut MissionView>,
        target: Option<Target>,
    ) -> Option<Target> {
        let now = Instant::now();
        let frame_secs = self
            .last_frame
            .map_or(0.0, |at| now.duration_since(at).as_secs_f64());
        self.last_frame = Some(now);
        if let Some(recording) = &mut self.recording {
            recording.advance(frame_secs);
            if recording.playing {
                ui.ctx().request_repaint();
            }
        }
        if self.is_running() {
            ui.ctx().request_repaint_after(Duration::from_millis(200));
        }
        let status = self.status();
        let mut start = None;
        egui::Panel::top("run-tools").show(ui, |ui| {
            start = self.toolbar_ui(ui, target, status.as_ref());
        });
        egui::Panel::left("run-modules")
            .resizable(true)
            .default_size(380.0)
            .min_size(300.0)
            .show(ui, |ui| self.modules_ui(ui, status.as_ref()));
        let legs: Vec<(String, String, String)> = mission
            .as_ref()
            .map(|mission| {
                mission
                    .watched_plan()
                    .legs
                    .iter()
                    .map(|leg| (leg.name.clone(), leg.from.clone(), leg.to.clone()))
                    .collect()
            })
            .unwrap_or_default();
        egui::Panel::right("run-mission")
            .resizable(true)
            .default_size(320.0)
            .min_size(260.0)
            .show(ui, |ui| {
                // The pad stays in one place whatever the length of the mission's lists.
                egui::Panel::bottom("run-drive")
                    .resizable(false)
                    .show(ui, |ui| self.teleop_ui(ui));
                egui::ScrollArea::vertical()
                    .id_salt("run-mission-scroll")
                    .show(ui, |ui| {
                        self.localisation_ui(ui);
                        self.mission_ui(ui, status.as_ref());
                        self.rehearsal_ui(ui, &legs);
                        self.views_ui(ui, status.as_ref());
                    });
            });
        egui::Panel::bottom("run-logs")
            .resizable(true)
            .default_size(180.0)
            .min_size(100.0)
            .show(ui, |ui| self.logs_ui(ui));
        egui::CentralPanel::default()
            .frame(egui::Frame::NONE)
            .show(ui, |ui| {
                self.map_and_net_ui(ui, viewer, mission, status.as_ref())
            });
        self.drive_keys(ui.ctx());
        start
    }

    fn toolbar_ui(
        &mut self,
        ui: &mut Ui,
        target: Option<Target>,
        status: Option<&Status>,
    ) -> Option<Target> {
        let mut start = None;
        ui.horizontal_wrapped(|ui| {
            let running = self.is_running();
            ui.add_enabled_ui(!running, |ui| {
                match &target {
                    Some(target) => {
                        let run = ui
                            .button(run_label(target))
                            .on_hover_text(format!("armor run {} (F5)", target.path().display()));
                        if run.clicked() {
                            start = Some(target.clone());
                        }
                    }
                    None => {
                        ui.add_enabled(false, egui::Button::new("▶ Run"))
                            .on_disabled_hover_text("open or save a system or a plan first");
                    }
                }
                ui.label("×");
                // While a run goes on, the box shows its own scale (an attached run's may be
                // any); the next run's is kept for when it ends.
                let mut run_scale = status.filter(|_| running).map(|status| status.time_scale);
                let scale = run_scale.as_mut().unwrap_or(&mut self.time_scale);
                ui.add(egui::DragValue::new(scale).range(0.1..=200.0).speed(0.1))
                    .on_hover_text("time scale: run time passes this many times faster")
                    // Every module keeps its own clock from the scale it was started with, and
                    // the run's control interface has no command to change it.
                    .on_disabled_hover_text(
                        "the run's time scale, set when it started: it cannot change while \
                         the run goes on (stop, then F5 asks it again)",
                    );
                ui.label("start at");
                ui.add(
                    egui::TextEdit::singleline(&mut self.start_at)
                        .desired_width(170.0)
                        .hint_text("the plan's start, or now"),
                );
                ui.label("secret");
                ui.add(
                    egui::TextEdit::singleline(&mut self.secret_file)
                        .desired_width(140.0)
                        .hint_text("none"),
                )
                .on_hover_text(
                    "a file with a shared secret (readable by its owner only): every \
                     connection of the run must prove it (armor run --secret)",
                );
            });
            let attached = self.session.as_ref().is_some_and(RunSession::is_attached);
            let (stop_label, stop_hover) = if attached {
                ("⏏ Detach", "stop watching: the run goes on (Shift+F5)")
            } else {
                ("■ Stop", "stop every module in order (Shift+F5)")
            };
            if ui
                .add_enabled(running, egui::Button::new(stop_label))
                .on_hover_text(stop_hover)
                .clicked()
            {
                self.stop();
            }
            ui.separator();
            ui.checkbox(&mut self.follow, "Follow")
                .on_hover_text("keep the map centred on the robot");
            if ui
                .button("Fit")
                .on_hover_text("frame the world, the plan and the robot (Home)")
                .clicked()
            {
                self.fit_pending = true;
            }
            ui.separator();
            let lost = self.session.as_ref().and_then(|session| {
                let shared = session.shared();
                let (since, why) = shared.connection_lost.clone()?;
                // The cause without the address, which the status line shows already.
                let cause = why.rsplit(": ").next().unwrap_or(&why);
                let ago = (session.elapsed_secs() - since).max(0.0);
                Some(if shared.status.is_some() {
                    format!(
                        "connection lost {ago:.0} s ago, retrying — {cause}; the state shown is \
                         the last known"
                    )
                } else {
                    format!("cannot reach the run, retrying — {cause}")
                })
            });
            if let (Some(lost), true) = (&lost, running) {
                ui.colored_label(ui.visuals().error_fg_color, lost);
            }
            let text = match (&self.session, status) {
                (Some(session), _) if session.is_stopping() => "stopping…".to_owned(),
                (Some(session), Some(status)) if session.is_attached() && session.is_running() => {
                    format!(
                        "attached to {} — {:.1} s of run time (×{})",
                        status.system, status.run_secs, status.time_scale
                    )
                }
                (Some(session), Some(status)) if session.is_running() => format!(
                    "{} — {:.1} s of run time (×{})",
                    status.system, status.run_secs, status.time_scale
                ),
                (Some(session), None) if session.is_running() => "starting…".to_owned(),
                (Some(session), _) if session.is_attached() => {
                    let at = session
                        .shared()
                        .control_addr
                        .map_or_else(String::new, |addr| format!(" at {addr}"));
                    format!("detached from the run{at}: it goes on without the studio")
                }
                _ => match (self.ended(), &target) {
                    (Some(ended), _) => format!("the run {ended}"),
                    (None, Some(target)) => {
                        format!("ready to run the {}", prompt::target_words(target))
                    }
                    (None, None) => "nothing to run".to_owned(),
                },
            };
            ui.label(text);
        });
        start
    }

    fn modules_ui(&mut self, ui: &mut Ui, status: Option<&Status>) {
        ui.heading("Modules");
        let Some(status) = status else {
            if self.is_detached() {
                ui.label(
                    "Detached: the run goes on without the studio, its modules unseen. \
                     Run → Attach… watches it again.",
                );
            } else {
                ui.label("Run the system or a plan to see its modules here.");
            }
            return;
        };
        let Some(session) = &self.session else {
            return;
        };
        let running = session.is_running() && self.may_command();
        let history = session.shared().history.clone();
        let mut requests = Vec::new();
        egui::ScrollArea::vertical()
            .id_salt("run-modules-scroll")
            .show(ui, |ui| {
                requests = oscilloscope::tree_ui(ui, status, &history, running);
                ui.heading("State changes");
                oscilloscope::timeline_ui(ui, status, &mut self.timeline_at);
            });
        for request in requests {
            self.request(request);
        }
    }

    /// Each module's own view: the switches of the markers' layers, and the inspector; the
    /// robot's sensors and motors.
    fn views_ui(&mut self, ui: &mut Ui, status: Option<&Status>) {
        let live = self.live();
        ui.separator();
        ui.heading("Markers");
        let stopped = markers::not_drawn(&BTreeSet::new(), &self.module_states());
        markers::toggles_ui(ui, &live.markers, &mut self.hidden_markers, &stopped);
        ui.separator();
        ui.heading("Inspect an output");
        inspector::inspector_ui(ui, &live.outputs, &mut self.inspected);
        ui.separator();
        egui::CollapsingHeader::new("Sensors and motors")
            .id_salt("run-sensors-motors")
            .show(ui, |ui| sensors_motors::panel_ui(ui, &live.outputs, status));
    }

    /// The localiser's state in words and colour, and the set-pose tool.
    fn localisation_ui(&mut self, ui: &mut Ui) {
        let live = self.live();
        let has_localiser = self.has_localiser();
        if live.estimate.is_none() && !has_localiser {
            return;
        }
        ui.heading("Localisation");
        match &live.estimate {
            Some(estimate) => {
                ui.horizontal_wrapped(|ui| {
                    ui.label(
                        RichText::new(format!(" {} ", estimate.state.as_str()))
                            .strong()
                            .color(Color32::WHITE)
                            .background_color(monitor::localisation_colour(estimate.state)),
                    );
                    let text = monitor::estimate_text(estimate);
                    let details = text.split_once(" · ").map_or("", |(_, rest)| rest);
                    ui.label(details);
                });
            }
            None => {
                ui.label("no estimate yet");
            }
        }
        let running = self.is_running();
        // With a key, the role is known once the control link proved it: until then (a new
        // attachment), the tool waits rather than offer an observer what it may not do.
        let proven = self.session.as_ref().is_none_or(|session| {
            session.options.secret.is_none() || session.shared().role.is_some()
        });
        let may = running && has_localiser && proven && self.may_command();
        let hint = if !self.may_command() {
            "attached with an observer's key: setting the pose needs an operator's"
        } else if !running {
            "during a run"
        } else {
            "a run with a localiser"
        };
        let tool = ui
            .add_enabled(
                may,
                egui::Button::selectable(self.set_pose_tool && may, "📍 Set pose"),
            )
            .on_hover_text(
                "press on the map where the robot is, drag towards its heading, release: the                  localiser starts again from there (armor ctl set-pose)",
            )
            .on_disabled_hover_text(hint);
        if tool.clicked() {
            self.set_pose_tool = !self.set_pose_tool;
            self.set_pose_from = None;
        }
        if !may {
            self.set_pose_tool = false;
            self.set_pose_from = None;
        }
        if self.set_pose_tool {
            ui.label(
                RichText::new("press where the robot is, drag towards its heading, release")
                    .small(),
            );
        }
        ui.separator();
    }

    /// A simulated plan run's verdict by the simulator's truth, once it ended: passed or failed
    /// with every reason, each no-go area's least distance, and the legs with their true
    /// errors.
    fn rehearsal_ui(&mut self, ui: &mut Ui, plan_legs: &[(String, String, String)]) {
        let Some(verdict) = self.rehearsal() else {
            return;
        };
        ui.separator();
        ui.heading("Rehearsal");
        let (word, colour) = if verdict.passed {
            ("passed", state_colour(ModuleState::Running))
        } else {
            ("FAILED", state_colour(ModuleState::Failed))
        };
        ui.label(
            RichText::new(format!(" {word} by the simulator's truth "))
                .strong()
                .color(Color32::WHITE)
                .background_color(colour),
        );
        for failure in &verdict.failures {
            ui.label(RichText::new(failure).color(colour));
        }
        if verdict.passed {
            ui.label(format!(
                "every arrival within {:.2} m of its waypoint, no footprint met a no-go area",
                verdict.allowed_m
            ));
        }
        for line in verdict.area_lines() {
            ui.label(RichText::new(line).small());
        }
        // The plan's legs, else (a run attached without its plan) the arrivals judged.
        let legs: Vec<(String, String)> = if plan_legs.is_empty() {
            verdict
                .arrivals
                .iter()
                .map(|arrival| (arrival.leg.clone(), arrival.waypoint.clone()))
                .collect()
        } else {
            plan_legs
                .iter()
                .map(|(name, from, to)| (name.clone(), format!("{from} to {to}")))
                .collect()
        };
        ui.label(RichText::new("Legs").strong());
        egui::Grid::new("run-rehearsal-legs")
            .striped(true)
            .show(ui, |ui| {
                for heading in ["leg", "way", "arrived", "true error"] {
                    ui.label(RichText::new(heading).strong());
                }
                ui.end_row();
                for (leg, way) in legs {
                    let arrival = verdict.arrivals.iter().find(|arrival| arrival.leg == leg);
                    ui.label(&leg);
                    ui.label(way);
                    ui.label(arrival.map_or("-".to_owned(), |arrival| {
                        format!("{:.1} s", arrival.arrived_secs)
                    }));
                    let error = verdict.true_error_text(&leg);
                    let failed = arrival.is_some_and(|arrival| !arrival.ok);
                    ui.label(if failed {
                        RichText::new(error).color(colour)
                    } else {
                        RichText::new(error)
                    });
                    ui.end_row();
                }
            });
    }

    fn mission_ui(&mut self, ui: &mut Ui, status: Option<&Status>) {
        ui.heading("Mission");
        let Some(mission) = status.and_then(|status| status.mission.as_ref()) else {
            ui.label("A plan's run shows its marking, what it waits for and its firings here.");
            return;
        };
        // An observer's key reads the run: its commands are greyed.
        let running = self.is_running() && self.may_command();
        let mut requests = Vec::new();
        ui.horizontal_wrapped(|ui| {
            if !self.may_command() {
                ui.label("attached as an observer: reading only");
            }
            ui.add_enabled_ui(running && mission.outcome.is_none(), |ui| {
                if mission.paused {
                    if ui.button("⏵ Resume").clicked() {
                        requests.push(Request::Resume);
                    }
                } else if ui
                    .button("⏸ Pause")
                    .on_hover_text("hold every controllable module; fire nothing")
                    .clicked()
                {
                    requests.push(Request::Pause);
                }
                if ui
                    .button("⏹ Abort")
                    .on_hover_text("end the mission now")
                    .clicked()
                {
                    requests.push(Request::Abort);
                }
            });
        });
        ui.label(format!(
            "`{}`{}: marking {}",
            mission.name,
            match (&mission.outcome, mission.paused) {
                (Some(outcome), _) => format!(" ({outcome})"),
                (None, true) => " (paused)".to_owned(),
                (None, false) => String::new(),
            },
            armor_model::net::marking_text(&mission.marking)
        ));
        if let Some(summary) = self.followed.summary().filter(|_| running) {
            ui.label(format!("Path: {summary}"));
        }
        if let Some(progress) = &mission.progress {
            progress::progress_ui(ui, progress);
        }
        let run_secs = status.map_or(0.0, |status| status.run_secs);
        if let Some(option) = self.repair_ui(ui, mission, run_secs) {
            requests.push(Request::Repair { option });
            self.updates.sending = true;
        }
        if !mission.enabled.is_empty() {
            ui.label(RichText::new("Next").strong());
        }
        for enabled in &mission.enabled {
            ui.horizontal_wrapped(|ui| {
                if ui
                    .add_enabled(
                        running,
                        egui::Button::new(format!("⏭ {}", enabled.transition)).small(),
                    )
                    .on_hover_text("fire it now, by hand, whatever it waits for")
                    .clicked()
                {
                    requests.push(Request::Fire {
                        transition: enabled.transition.clone(),
                    });
                }
                if !enabled.waits_for.is_empty() {
                    ui.label(format!("waits for {}", enabled.waits_for.join(", ")));
                }
            });
        }
        ui.label(RichText::new(format!("Firings ({})", mission.firings_total)).strong());
        monitor::timeline_ui(ui, &mission.firings);
        self.updates_ui(ui, mission);
        for request in requests {
            self.request(request);
        }
    }

    fn teleop_ui(&mut self, ui: &mut Ui) {
        ui.label(RichText::new("Drive").strong());
        let can_drive = self.session.as_ref().is_some_and(|s| {
            s.is_running() && s.shared().status.as_ref().is_some_and(session::can_drive)
        });
        if !can_drive {
            ui.label("A running system with a teleop module can be driven from here.");
            return;
        }
        if !self.may_command() {
            ui.label("Attached with an observer's key: driving needs an operator's.");
            return;
        }
        let mut held = (0.0, 0.0);
        egui::Grid::new("teleop-pad").show(ui, |ui| {
            ui.label("");
            if monitor::pad_button(ui, egui::vec2(0.0, -1.0), "forward") {
                held.0 += DRIVE_MPS;
            }
            ui.end_row();
            if monitor::pad_button(ui, egui::vec2(-1.0, 0.0), "turn left") {
                held.1 += TURN_RADPS;
            }
            if monitor::pad_button(ui, egui::vec2(0.0, 1.0), "back") {
                held.0 -= DRIVE_MPS;
            }
            if monitor::pad_button(ui, egui::vec2(1.0, 0.0), "turn right") {
                held.1 -= TURN_RADPS;
            }
            ui.end_row();
        });
        ui.label(
            RichText::new(
                "Hold a button or an arrow key to drive; let go and the robot stops (and if the \
                 studio stops sending, the teleop module's dead-man time stops it).",
            )
            .small()
            .weak(),
        );
        if held != (0.0, 0.0) {
            self.drive = held;
        }
    }

    /// Arrow keys over the map drive; the pad's command is folded in. Sends the command again
    /// while held, and `stop` when let go.
    fn drive_keys(&mut self, ctx: &egui::Context) {
        // The video panel takes the focus to drive by the camera.
        let typing = ctx.egui_wants_keyboard_input() && !video::has_focus(ctx);
        let mut command = std::mem::take(&mut self.drive);
        if !typing {
            ctx.input(|input| {
                if input.key_down(egui::Key::ArrowUp) {
                    command.0 += DRIVE_MPS;
                }
                if input.key_down(egui::Key::ArrowDown) {
                    command.0 -= DRIVE_MPS;
                }
                if input.key_down(egui::Key::ArrowLeft) {
                    command.1 += TURN_RADPS;
                }
                if input.key_down(egui::Key::ArrowRight) {
                    command.1 -= TURN_RADPS;
                }
            });
        }
        let Some(session) = &self.session else {
            return;
        };
        let now = Instant::now();
        if command != (0.0, 0.0) {
            if self
                .drive_sent
                .is_none_or(|at| now.duration_since(at) >= session::TELEOP_EVERY)
            {
                session.teleop(command.0, command.1);
                self.drive_sent = Some(now);
            }
            ctx.request_repaint_after(session::TELEOP_EVERY);
        } else if self.drive_sent.take().is_some() {
            session.teleop(0.0, 0.0);
        }
    }

    fn logs_ui(&mut self, ui: &mut Ui) {
        let Some(session) = &self.session else {
            ui.label("Each module's log shows here during a run.");
            return;
        };
        if session.is_attached() && session.shared().logs.is_empty() {
            // Not an empty log: the lines go to the terminal and the run folder of `armor run`.
            ui.label(
                "Attached to a run started elsewhere: its modules' logs stay where it runs (the \
                 terminal of `armor run`, and `log.txt` in its run folder).",
            );
            return;
        }
        let shared = session.shared();
        let mut sources: Vec<&str> = shared.logs.iter().map(|l| l.source.as_str()).collect();
        sources.sort_unstable();
        sources.dedup();
        let sources: Vec<String> = sources.into_iter().map(str::to_owned).collect();
        drop(shared);
        ui.horizontal(|ui| {
            ui.label("Logs");
            egui::ComboBox::from_id_salt("log-module")
                .selected_text(self.log_module.as_deref().unwrap_or("all modules"))
                .show_ui(ui, |ui| {
                    ui.selectable_value(&mut self.log_module, None, "all modules");
                    for source in &sources {
                        ui.selectable_value(&mut self.log_module, Some(source.clone()), source);
                    }
                });
            egui::ComboBox::from_id_salt("log-level")
                .selected_text(match self.log_min_level {
                    Level::Info => "everything",
                    Level::Warn => "warnings and errors",
                    Level::Error => "errors",
                })
                .show_ui(ui, |ui| {
                    ui.selectable_value(&mut self.log_min_level, Level::Info, "everything");
                    ui.selectable_value(
                        &mut self.log_min_level,
                        Level::Warn,
                        "warnings and errors",
                    );
                    ui.selectable_value(&mut self.log_min_level, Level::Error, "errors");
                });
            ui.add(
                egui::TextEdit::singleline(&mut self.log_filter)
                    .hint_text("filter")
                    .desired_width(200.0),
            );
        });
        let filter = self.log_filter.to_lowercase();
        let shared = session.shared();
        let lines: Vec<&session::LogLine> = shared
            .logs
            .iter()
            .filter(|line| self.log_module.as_ref().is_none_or(|m| &line.source == m))
            .filter(|line| level_rank(line.level) >= level_rank(self.log_min_level))
            .filter(|line| filter.is_empty() || line.text.to_lowercase().contains(&filter))
            .collect();
        let row_height = ui.text_style_height(&egui::TextStyle::Monospace);
        egui::ScrollArea::both()
            .id_salt("run-logs-scroll")
            .stick_to_bottom(true)
            .auto_shrink(false)
            .show_rows(ui, row_height, lines.len(), |ui, range| {
                for line in &lines[range] {
                    let colour = match line.level {
                        Level::Error => Color32::from_rgb(200, 40, 40),
                        Level::Warn => Color32::from_rgb(190, 120, 0),
                        Level::Info => ui.visuals().text_color(),
                    };
                    ui.label(
                        RichText::new(format!(
                            "{:>7.2} [{}] {}",
                            line.at_secs, line.source, line.text
                        ))
                        .monospace()
                        .color(colour),
                    );
                }
            });
    }

    fn map_and_net_ui(
        &mut self,
        ui: &mut Ui,
        viewer: &ViewerContext,
        mut mission: Option<&mut MissionView>,
        status: Option<&Status>,
    ) {
        let marking = status
            .and_then(|status| status.mission.as_ref())
            .map(|mission| mission.marking.clone());
        let has_plan_run = marking.is_some() && mission.is_some();
        if has_plan_run
            && let Some(mission) = mission.as_deref_mut()
            && let Some(marking) = &marking
        {
            mission.net_panel_ui(ui, "run-net", 200.0, |mission, ui| {
                mission.marking_ui(ui, marking);
            });
        }
        if let Some(recording) = &mut self.recording {
            egui::Panel::top("run-recording").show(ui, |ui| recording_ui(ui, recording));
        }
        let live = self.live();
        let current_leg = marking.as_ref().and_then(|marking| {
            let mission = mission.as_deref()?;
            let compiled = mission.watched_checked().compiled.as_ref()?;
            marking
                .keys()
                .find_map(|place| match compiled.trace.get(place) {
                    Some(Origin::Leg(index)) => Some(*index),
                    _ => None,
                })
        });
        let grid_texture = self.grid_texture(ui.ctx(), &live);
        // The net appears above the map once the run reports its marking, and the map shrinks:
        // it is framed again then, or the robot's start may be left below its edge.
        let net_appeared = has_plan_run && !self.net_shown;
        self.net_shown = has_plan_run;
        let fit = std::mem::take(&mut self.fit_pending) || net_appeared;
        let follow = self.follow;
        let max_replans = self.max_replans;
        // A module's markers go when it stops: what they said is no longer so.
        let not_drawn = markers::not_drawn(&self.hidden_markers, &self.module_states());
        let watching = self.is_running() || self.recording.is_some();
        let verdict = self.rehearsal();
        let set_pose_tool = self.set_pose_tool;
        let mut set_pose_from = self.set_pose_from;
        // The camera beside the map.
        let images = self
            .sources()
            .map(|sources| sources.images)
            .unwrap_or_default();
        if !images.is_empty() {
            let clock = match &self.recording {
                Some(recording) => video::Clock::PlayHead(recording.play_head_ns()),
                None => video::Clock::Live,
            };
            egui::Panel::right("run-video")
                .resizable(true)
                .default_size(360.0)
                .show(ui, |ui| self.video.ui(ui, &images, &live.video, clock));
        }
        let mission = match (
            self.session.as_ref().map(|s| s.options.target.clone()),
            mission,
        ) {
            (Some(target), Some(mission)) if mission.path() == Some(target.as_path()) => mission,
            (Some(target), _) => self.own_map(&target, viewer.catalog(), ui.ctx()),
            (None, Some(mission)) => mission,
            (None, None) => match viewer.system_file.as_deref() {
                Some(system) => self.own_map(system, viewer.catalog(), ui.ctx()),
                None => {
                    ui.centered_and_justified(|ui| ui.label("Open a system or a plan to run it."));
                    return;
                }
            },
        };
        if fit {
            mission.request_fit();
        }
        if follow && let Some(pose) = live.estimated.as_ref().or(live.truth.as_ref()) {
            mission.centre_on(armor_model::world::Point::new(pose.x_m, pose.y_m));
        }
        let planned = current_leg.and_then(|leg| match mission.watched_checked().legs.get(leg) {
            Some(LegRoute::Path { points, .. }) => Some(points.as_slice()),
            _ => None,
        });
        // A plan's run without a current leg (before the first, after the last) has no path to
        // tell the replans by: what the follower published then is not shown.
        let followed = if current_leg.is_some() || !has_plan_run {
            FollowedLeg::of(&live.followed, planned, max_replans)
        } else {
            FollowedLeg::default()
        };
        // What the map shows, in words, on a line above it rather than over it, where it hid
        // the plan's labels.
        // Once the run is over, nothing is being followed (the paths stay drawn as they were).
        let followed_text = followed.summary().filter(|_| watching);
        if live.samples > 0 || live.refused.is_some() || verdict.is_some() {
            egui::Panel::top("run-map-status").show(ui, |ui| {
                if let Some(verdict) = &verdict {
                    let colour = if verdict.passed {
                        state_colour(ModuleState::Running)
                    } else {
                        state_colour(ModuleState::Failed)
                    };
                    ui.label(RichText::new(verdict.headline()).strong().color(colour));
                }
                ui.horizontal_wrapped(|ui| {
                    if let Some(estimate) = &live.estimate {
                        ui.label(
                            RichText::new(format!(" {} ", estimate.state.as_str()))
                                .strong()
                                .color(Color32::WHITE)
                                .background_color(monitor::localisation_colour(estimate.state)),
                        );
                    }
                    if live.samples > 0 {
                        ui.label(monitor::pose_text(&live));
                    }
                    if let Some(text) = &followed_text {
                        ui.label("·");
                        ui.label(text);
                    }
                });
                if let Some(refused) = &live.refused {
                    ui.label(
                        RichText::new(format!("not shown: {refused}"))
                            .color(state_colour(ModuleState::Failed)),
                    );
                }
            });
        }
        let mut drawn = BTreeMap::new();
        let mut layout = MapLayout::default();
        // Text is measured as the map will draw it (the tags are placed with its labels).
        let ui_painter = ui.painter().clone();
        let keep_clear = |project: &dyn Fn(armor_model::world::Point) -> egui::Pos2| {
            monitor::robot_tags(&ui_painter, project, &live)
        };
        let map = mission.watch_ui(
            ui,
            current_leg,
            &keep_clear,
            Box::new(|painter, project, labels, leaders, bounds, tags| {
                monitor::paint_live(painter, project, &live, grid_texture.as_ref(), &followed);
                let mut taken = labels.to_vec();
                taken.extend(monitor::robot_boxes(project, &live));
                let texts;
                (drawn, texts) = markers::paint(
                    painter,
                    project,
                    &live.markers,
                    &not_drawn,
                    live.scan_pose(),
                    &taken,
                    leaders,
                    bounds,
                );
                // The robots last: over the markers (an observer's arc, a goal's dot) and
                // the paths, so that nothing hides them.
                monitor::paint_robots(painter, project, &live, tags);
                layout.robots = monitor::robot_boxes(project, &live);
                layout.labels = labels
                    .iter()
                    .copied()
                    .chain(texts.iter().map(|text| text.rect))
                    .collect();
                layout.bounds = Some(bounds);
            }),
        );
        let set_pose = set_pose_tool
            .then(|| set_pose_ui(ui, &map, mission, &mut set_pose_from))
            .flatten();
        self.markers_drawn = drawn;
        self.map_layout = layout;
        self.followed = followed;
        self.set_pose_from = set_pose_from;
        if let Some(request) = set_pose {
            self.set_pose_tool = false;
            self.request(request);
        }
    }

    /// The grid's picture, made again only when a new grid arrived. Its size is the grid's,
    /// shrunk to what the display takes as one texture.
    fn grid_texture(
        &mut self,
        ctx: &egui::Context,
        live: &LiveData,
    ) -> Option<(egui::TextureHandle, Arc<OccupancyGrid>)> {
        let grid = live.grid.as_ref()?;
        if self
            .grid_texture
            .as_ref()
            .is_none_or(|(revision, _)| *revision != live.grid_revision)
        {
            let max_side = ctx.input(|input| input.max_texture_side);
            match monitor::grid_image(grid, max_side) {
                Ok(image) => {
                    let texture =
                        ctx.load_texture("run-grid", image, egui::TextureOptions::NEAREST);
                    self.grid_texture = Some((live.grid_revision, texture));
                }
                // `LiveData::take` refuses such a grid before it is kept, and says why.
                Err(refused) => {
                    tracing::debug!("no picture of the grid: {refused}");
                    self.grid_texture = None;
                    return None;
                }
            }
        }
        self.grid_texture
            .as_ref()
            .map(|(_, texture)| (texture.clone(), Arc::clone(grid)))
    }
}

/// The set-pose tool on the map: over the map's own dragging, a press is where the robot is
/// and the drag its heading, drawn as an arrow; the release makes the request.
fn set_pose_ui(
    ui: &mut Ui,
    map: &egui::Response,
    mission: &MissionView,
    from: &mut Option<armor_model::world::Point>,
) -> Option<Request> {
    let response = ui
        .interact(
            map.rect,
            egui::Id::new("run-set-pose"),
            egui::Sense::click_and_drag(),
        )
        .on_hover_cursor(egui::CursorIcon::Crosshair);
    let pressed_at = ui.input(|input| input.pointer.press_origin());
    if response.drag_started() {
        *from = pressed_at.and_then(|at| mission.world_at(at));
    }
    let start = (*from).and_then(|from| Some((from, mission.last_screen_of(from)?.0)));
    let pointer = response
        .interact_pointer_pos()
        .or_else(|| ui.input(|input| input.pointer.latest_pos()));
    if let (Some((_, start)), Some(pointer)) = (start, pointer) {
        let colour = Color32::from_rgb(150, 40, 200);
        ui.painter()
            .circle_stroke(start, 10.0, Stroke::new(2.5, colour));
        if (pointer - start).length() >= SET_POSE_MIN_DRAG {
            ui.painter()
                .arrow(start, pointer - start, Stroke::new(3.0, colour));
        }
    }
    if !response.drag_stopped() {
        return None;
    }
    *from = None;
    let (from, start) = start?;
    let pointer = pointer?;
    if (pointer - start).length() < SET_POSE_MIN_DRAG {
        return None;
    }
    let to = mission.world_at(pointer)?;
    let heading_deg = (to.y - from.y).atan2(to.x - from.x).to_degrees();
    // Centimetres and tenths of a degree: what a hand on a map can mean. Divided rather than
    // multiplied by the step, so that the value prints as short as it reads (7.1, not
    // 7.1000000000000005).
    let round = |value: f64, per_unit: f64| (value * per_unit).round() / per_unit;
    Some(Request::SetPose {
        x_m: round(from.x, 100.0),
        y_m: round(from.y, 100.0),
        heading_deg: round(heading_deg, 10.0),
        module: None,
    })
}

/// The `max_replans` of the module that publishes `path` (`follower.path`): its value in
/// `system`, else its default in the module's description.
fn max_replans(system: &armor_model::SystemConfig, path: &str, catalog: &Catalog) -> Option<u32> {
    let (name, _) = path.split_once('.')?;
    let module = system.modules.iter().find(|module| module.name == name)?;
    let value = module
        .params
        .iter()
        .find(|param| param.name == "max_replans")
        .map(|param| param.value.clone())
        .or_else(|| {
            catalog
                .get(&module.module_type)?
                .params
                .iter()
                .find(|param| param.name == "max_replans")?
                .default
                .clone()
        })?;
    value.trim().parse().ok()
}

fn level_rank(level: Level) -> u8 {
    match level {
        Level::Info => 0,
        Level::Warn => 1,
        Level::Error => 2,
    }
}

fn recording_ui(ui: &mut Ui, recording: &mut Recording) {
    ui.horizontal(|ui| {
        ui.label(format!(
            "Recording {}",
            recording
                .file
                .file_name()
                .map(|name| name.to_string_lossy().into_owned())
                .unwrap_or_default()
        ));
        let label = if recording.playing { "⏸" } else { "⏵" };
        if ui
            .button(label)
            .on_hover_text("play or pause the recording")
            .clicked()
        {
            if !recording.playing && recording.at_secs >= recording.duration_secs {
                recording.seek(0.0);
            }
            recording.playing = !recording.playing;
        }
        let mut at = recording.at_secs;
        let slider = egui::Slider::new(&mut at, 0.0..=recording.duration_secs.max(0.001))
            .suffix(" s")
            .text("time");
        if ui.add(slider).changed() {
            recording.seek(at);
        }
    });
}

/// The plan a run of `target` plays, read from its file (just saved, or the copy of an attached
/// run's): `None` for a system, or a file that does not read as a plan (the run says why).
fn plan_of(target: &Target) -> Option<updates::RunPlan> {
    let Target::Plan(path) = target else {
        return None;
    };
    let text = std::fs::read_to_string(path)
        .map_err(|err| tracing::warn!("cannot read {}: {err}", path.display()))
        .ok()?;
    updates::RunPlan::of_text(&text, &path.display().to_string())
        .map_err(|why| tracing::warn!("{why}"))
        .ok()
}

/// What the Run view's map drew at its last frame, for tests of its layout.
#[derive(Clone, Debug, Default)]
pub struct MapLayout {
    /// Every label's box: the plan's, the robots' tags, the markers' texts.
    pub labels: Vec<egui::Rect>,
    /// The robots' boxes (the estimate's disc, the truth's ring).
    pub robots: Vec<egui::Rect>,
    /// The rectangle the labels were kept in: the world's on screen (none before a frame).
    pub bounds: Option<egui::Rect>,
}

/// The Run button's text: what it runs ("▶ Run plan", "▶ Run system"), its file in the hover.
pub fn run_label(target: &Target) -> &'static str {
    match target {
        Target::Plan(_) => "▶ Run plan",
        Target::System(_) => "▶ Run system",
    }
}
